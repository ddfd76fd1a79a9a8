// SPDX-License-Identifier: MIT
#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace occ {
namespace {

namespace fs = std::filesystem;

size_t filesIn(const fs::path& dir) {
    size_t n = 0;
    for (const auto& e : fs::directory_iterator(dir)) n += e.is_regular_file();
    return n;
}

TEST(AtomicFile, ACommittedFileIsWholeAndAnUncommittedOneLeavesTheOldFileAlone) {
    const fs::path dir = test::scratchDir() / "atomic";
    fs::create_directories(dir);
    const std::string path = (dir / "out.txt").string();
    writeFileAtomic(path, "first\n");
    EXPECT_EQ(test::readBytes(path), (std::vector<char>{'f', 'i', 'r', 's', 't', '\n'}));
    {
        AtomicFile f(path);
        f.write("second, never committed");
        EXPECT_EQ(filesIn(dir), 2u);  // the old file and the temporary
    }
    EXPECT_EQ(test::readBytes(path).size(), 6u);
    EXPECT_EQ(filesIn(dir), 1u) << "the temporary is removed";
    {
        AtomicFile f(path);
        f.write("third");
        f.commit();
        EXPECT_THROW(f.commit(), InputError);
    }
    EXPECT_EQ(test::readBytes(path).size(), 5u);
    EXPECT_EQ(filesIn(dir), 1u);
}

TEST(AtomicFile, AMissingFolderIsAnErrorNamingTheFile) {
    const std::string path = (test::scratchDir() / "no" / "such" / "out.txt").string();
    try {
        writeFileAtomic(path, "x");
        FAIL() << "wrote into a missing folder";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), path);
    }
}

TEST(AtomicFile, OutputFoldersAreMadeAndAFileInTheWayIsAnError) {
    const fs::path dir = test::scratchDir() / "made" / "deep";
    makeOutputFolder(dir.string());
    EXPECT_TRUE(fs::is_directory(dir));
    makeOutputFolder(dir.string());  // again: nothing to do
    const std::string file = test::writeFixture("plain.txt", "x");
    EXPECT_THROW(makeOutputFolder(file), InputError);
}

}  // namespace
}  // namespace occ
