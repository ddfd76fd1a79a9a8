// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace occ {

// CSV as occswitch writes it (stats, bench results) and reads it back: comma-separated fields,
// a field with a comma, quote or line break in double quotes with inner quotes doubled (RFC 4180).

// `text` as one field: as it is, or quoted when it needs to be.
std::string csvField(const std::string& text);

// `fields` as one line, without the line break.
std::string csvRow(const std::vector<std::string>& fields);

// The fields of one line; InputError(source, "line N: ...") for an unterminated quote.
std::vector<std::string> csvFields(std::string_view line, const std::string& source = "CSV", size_t line_number = 1);

// A CSV file with a header row, read whole. Every failure (no file, no header, a row whose field
// count differs from the header's, no rows, a column asked for that it lacks) is an InputError
// naming the file and, for a row, its line.
class CsvTable {
public:
    static CsvTable read(const std::string& path);
    static CsvTable parse(std::string_view text, const std::string& source);

    bool has(const std::string& column) const;
    size_t col(const std::string& column) const;
    size_t rows() const { return rows_.size(); }
    const std::vector<std::string>& header() const { return header_; }
    const std::vector<std::string>& row(size_t r) const { return rows_[r]; }
    const std::string& text(size_t row, size_t column) const { return rows_[row][column]; }
    // The field as a number; NaN when it is empty or not a number.
    double num(size_t row, size_t column) const;
    double num(size_t row, const std::string& column) const { return num(row, col(column)); }
    const std::string& source() const { return source_; }

private:
    std::string source_;
    std::vector<std::string> header_;
    std::vector<std::vector<std::string>> rows_;
};

}  // namespace occ
