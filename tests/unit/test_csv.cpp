// SPDX-License-Identifier: MIT
// The one CSV reader and writer (scene/csv.h).
#include "scene/csv.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cmath>

namespace occ {
namespace {

TEST(Csv, FieldsRoundTripThroughQuoting) {
    const std::vector<std::string> fields{"plain", "with,comma", "with \"quotes\"", "", "12.5"};
    const std::string line = csvRow(fields);
    EXPECT_EQ(line, "plain,\"with,comma\",\"with \"\"quotes\"\"\",,12.5");
    EXPECT_EQ(csvFields(line), fields);
    EXPECT_EQ(csvFields("a,b\r"), (std::vector<std::string>{"a", "b"}));  // CRLF files
    EXPECT_EQ(csvFields(""), std::vector<std::string>{""});
    EXPECT_THROW(csvFields("a,\"open"), InputError);
}

TEST(Csv, ATableReadsColumnsByNameAndNumbers) {
    const std::string path = test::writeFixture("t.csv", "frame,ms_total,name\n0,12.5,a\n\n1,,\"b,c\"\n2,x,d\n");
    const CsvTable t = CsvTable::read(path);
    ASSERT_EQ(t.rows(), 3u);
    EXPECT_TRUE(t.has("ms_total"));
    EXPECT_FALSE(t.has("fps"));
    EXPECT_EQ(t.num(0, "ms_total"), 12.5);
    EXPECT_TRUE(std::isnan(t.num(1, "ms_total")));  // empty
    EXPECT_TRUE(std::isnan(t.num(2, "ms_total")));  // not a number
    EXPECT_EQ(t.text(1, t.col("name")), "b,c");
    try {
        (void)t.col("fps");
        ADD_FAILURE() << "a missing column was found";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), path);
    }
}

TEST(Csv, BrokenTablesNameTheFileAndLine) {
    const auto message = [](const std::string& text) {
        try {
            (void)CsvTable::parse(text, "s.csv");
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_EQ(message(""), "s.csv: empty CSV (no header)");
    EXPECT_EQ(message("a,b\n"), "s.csv: no rows after the header");
    EXPECT_EQ(message("a,b\n1,2\n1,2,3\n"), "s.csv: line 3 has 3 fields, the header 2");
    EXPECT_EQ(message("a,b\n1,\"2\n"), "s.csv: line 2: a quoted field is not closed");
    EXPECT_THROW(CsvTable::read(test::scratchDir().string() + "/no_such.csv"), InputError);
}

}  // namespace
}  // namespace occ
