// SPDX-License-Identifier: MIT
#include "scene/csv.h"

#include "scene/errors.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

namespace occ {

std::string csvField(const std::string& text) {
    if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
    std::string quoted = "\"";
    for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    return quoted + "\"";
}

std::string csvRow(const std::vector<std::string>& fields) {
    std::string line;
    for (size_t i = 0; i < fields.size(); ++i) {
        if (i) line += ',';
        line += csvField(fields[i]);
    }
    return line;
}

std::vector<std::string> csvFields(std::string_view line, const std::string& source, size_t line_number) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    std::vector<std::string> fields(1);
    bool quoted = false;
    for (size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (quoted) {
            if (c != '"') {
                fields.back() += c;
            } else if (i + 1 < line.size() && line[i + 1] == '"') {
                fields.back() += '"';
                ++i;
            } else {
                quoted = false;
            }
        } else if (c == ',') {
            fields.emplace_back();
        } else if (c == '"') {
            quoted = true;
        } else {
            fields.back() += c;
        }
    }
    if (quoted) throw InputError(source, "line " + std::to_string(line_number) + ": a quoted field is not closed");
    return fields;
}

CsvTable CsvTable::read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot read: " + std::string(std::strerror(errno)));
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw InputError(path, "read error");
    return parse(text, path);
}

CsvTable CsvTable::parse(std::string_view text, const std::string& source) {
    CsvTable t;
    t.source_ = source;
    size_t at = 0, line_number = 0;
    while (at < text.size()) {
        size_t end = text.find('\n', at);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(at, end - at);
        at = end + 1;
        ++line_number;
        if (line.empty() || line == "\r") continue;
        std::vector<std::string> fields = csvFields(line, source, line_number);
        if (t.header_.empty()) {
            t.header_ = std::move(fields);
            continue;
        }
        if (fields.size() != t.header_.size())
            throw InputError(source, "line " + std::to_string(line_number) + " has " + std::to_string(fields.size()) +
                                         " fields, the header " + std::to_string(t.header_.size()));
        t.rows_.push_back(std::move(fields));
    }
    if (t.header_.empty()) throw InputError(source, "empty CSV (no header)");
    if (t.rows_.empty()) throw InputError(source, "no rows after the header");
    return t;
}

bool CsvTable::has(const std::string& column) const {
    return std::find(header_.begin(), header_.end(), column) != header_.end();
}

size_t CsvTable::col(const std::string& column) const {
    const auto it = std::find(header_.begin(), header_.end(), column);
    if (it == header_.end()) throw InputError(source_, "no column '" + column + "'");
    return size_t(it - header_.begin());
}

double CsvTable::num(size_t row, size_t column) const {
    const std::string& s = rows_[row][column];
    if (s.empty()) return NAN;
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    return end == s.c_str() || *end != '\0' ? NAN : v;
}

}  // namespace occ
