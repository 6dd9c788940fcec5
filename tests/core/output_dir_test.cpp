// Output folders that never lie (core/output_dir.h, issue 21 item 4): staging and commit, the
// refusals made before any work, the lock, and the recovery of what killed runs left.
#include "core/error.h"
#include "core/file_util.h"
#include "core/output_dir.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

namespace specula {
namespace {

namespace fs = std::filesystem;

// The names in a folder, sorted.
std::vector<std::string> names(const fs::path& dir) {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
}

bool always(const fs::path&) { return true; }

// The message of the exception of type E that fn throws ("" when it throws none).
template <class E, class Fn>
std::string message_of(Fn&& fn) {
    try {
        fn();
    } catch (const E& e) {
        return e.what();
    }
    return "";
}

TEST(OutputFolder, NewFolderAppearsOnlyOnCommit) {
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    {
        OutputFolder folder(out);
        EXPECT_EQ(folder.path(), out);
        EXPECT_EQ(folder.staging().parent_path(), dir.path());
        EXPECT_EQ(folder.staging().filename().string().rfind(".out.tmp-" + std::to_string(::getpid()) + "-", 0), 0u);
        EXPECT_TRUE(fs::exists(dir / ".out.lock")); // held while the run goes on
        write_text_file(folder.staging() / "a.txt", "new\n");
        EXPECT_FALSE(fs::exists(out));
        folder.commit();
        EXPECT_EQ(read_text_file(out / "a.txt"), "new\n");
    }
    EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"}); // no staging folder, no lock file left
}

TEST(OutputFolder, WithoutCommitThePreviousResultStays) {
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    fs::create_directory(out);
    write_text_file(out / "a.txt", "old\n");
    {
        OutputFolder folder(out, {.is_previous = always});
        write_text_file(folder.staging() / "a.txt", "half");
    } // an error: no commit
    EXPECT_EQ(read_text_file(out / "a.txt"), "old\n");
    EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"});
    // write_folder_atomically: a throwing writer leaves OUT as it was too.
    EXPECT_THROW(write_folder_atomically(out, {.is_previous = always},
                                         [](const fs::path& s) {
                                             write_text_file(s / "a.txt", "half");
                                             throw Error("stage failed");
                                         }),
                 Error);
    EXPECT_EQ(read_text_file(out / "a.txt"), "old\n");
    EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"});
}

TEST(OutputFolder, ReplacesTheWholeFolderBothWays) {
    for (const bool exchange : {true, false}) {
        SCOPED_TRACE(exchange ? "renameat2 exchange" : "two renames");
        const test::TempDir dir("outdir");
        const fs::path out = dir / "out";
        fs::create_directories(out / "sub");
        write_text_file(out / "a.txt", "old\n");
        write_text_file(out / "sub" / "stale.txt", "only in the old result\n");
        const fs::path written = write_folder_atomically(out, {.is_previous = always, .exchange = exchange},
                                                         [](const fs::path& s) { write_text_file(s / "a.txt", "new\n"); });
        EXPECT_EQ(written, out);
        EXPECT_EQ(read_text_file(out / "a.txt"), "new\n");
        EXPECT_EQ(names(out), std::vector<std::string>{"a.txt"}); // nothing of the old one is left inside
        EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"});
    }
}

TEST(OutputFolder, NonEmptyFolderNeedsToBeAnEarlierResultOrForce) {
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    fs::create_directory(out);
    write_text_file(out / "notes.txt", "the user's\n");
    const std::string why = message_of<UsageError>([&] { OutputFolder f(out, {.is_previous = [](const fs::path&) { return false; }}); });
    EXPECT_NE(why.find("is not empty and holds no earlier result of this command"), std::string::npos) << why;
    EXPECT_NE(why.find("--force"), std::string::npos) << why;
    EXPECT_THROW(OutputFolder(out, {}), UsageError); // no is_previous: every non-empty folder needs force
    EXPECT_EQ(names(out), std::vector<std::string>{"notes.txt"});
    EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"}); // the lock is released on refusal
    EXPECT_NO_THROW(OutputFolder(out, {.force = true}));
    // An empty folder needs nothing.
    fs::create_directory(dir / "empty");
    EXPECT_NO_THROW(OutputFolder(dir / "empty", {}));
}

TEST(OutputFolder, RefusesFilesDevicesAndPathsUnderAFile) {
    const test::TempDir dir("outdir");
    write_text_file(dir / "file", "x");
    std::string why = message_of<UsageError>([&] { OutputFolder f(dir / "file"); });
    EXPECT_NE(why.find("exists and is not a folder"), std::string::npos) << why;
    why = message_of<UsageError>([&] { OutputFolder f("/dev/null", {.option = "-o"}); });
    EXPECT_NE(why.find("-o: '/dev/null' exists and is not a folder (it is a device)"), std::string::npos) << why;
    EXPECT_FALSE(fs::exists("/dev/.null.lock"));
    why = message_of<InputError>([&] { OutputFolder f(dir / "file" / "sub" / "out"); });
    EXPECT_NE(why.find("cannot create the output folder: '" + (dir / "file").string() + "' is a file, not a folder"),
              std::string::npos)
        << why;
    EXPECT_THROW(OutputFolder("/"), UsageError);
    EXPECT_THROW(OutputFolder(""), UsageError);
}

TEST(OutputFolder, RefusesAFolderThatIsOrHoldsAnInput) {
    const test::TempDir dir("outdir");
    fs::create_directories(dir / "cap" / "images");
    write_text_file(dir / "cap" / "capture.json", "{}");
    write_text_file(dir / "cap" / "images" / "a.png", "x");
    const OutputFolderOptions options{.force = true, .inputs = {dir / "cap", dir / "cap" / "images" / "a.png"}};
    std::string why = message_of<UsageError>([&] { OutputFolder f(dir / "cap", options); });
    EXPECT_NE(why.find("is an input of this run"), std::string::npos) << why;
    why = message_of<UsageError>([&] { OutputFolder f(dir.path(), options); });
    EXPECT_NE(why.find("contains an input of this run (" + (dir / "cap").string() + ")"), std::string::npos) << why;
    why = message_of<UsageError>([&] { OutputFolder f(dir / "cap" / "images", options); });
    EXPECT_NE(why.find("contains an input of this run (" + (dir / "cap" / "images" / "a.png").string() + ")"),
              std::string::npos)
        << why;
    // Through a symbolic link, and spelled with "..": the same folders.
    fs::create_directory_symlink(dir / "cap", dir / "link");
    EXPECT_THROW(OutputFolder(dir / "link", options), UsageError);
    EXPECT_THROW(OutputFolder(dir / "cap" / "images" / ".." / "images", options), UsageError);
    // A folder beside the inputs, or inside the capture's folder but holding none, is fine.
    EXPECT_NO_THROW(OutputFolder(dir / "cap" / "out", options));
    EXPECT_NO_THROW(OutputFolder(dir / "out", options));
    EXPECT_EQ(names(dir / "cap"), (std::vector<std::string>{"capture.json", "images"}));
}

TEST(OutputFolder, RefusesWhereNothingCanBeCreated) {
    // /proc takes no new files: the lock file cannot be made, before any work.
    const std::string why = message_of<InputError>([] { OutputFolder f("/proc/specula-out"); });
    EXPECT_NE(why.find("/proc/specula-out: --out: cannot create the output folder here"), std::string::npos) << why;
}

TEST(OutputFolder, ASecondRunOnTheSameFolderIsRefused) {
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    std::optional<OutputFolder> first(std::in_place, out);
    const std::string why = message_of<InputError>([&] { OutputFolder second(out); });
    EXPECT_NE(why.find(out.string() + ": --out: another specula run (pid " + std::to_string(::getpid()) +
                       ") is writing this output folder"),
              std::string::npos)
        << why;
    // The refused run touched nothing of the first one's.
    EXPECT_TRUE(fs::is_directory(first->staging()));
    write_text_file(first->staging() / "a.txt", "first\n");
    first->commit();
    first.reset();
    // Once the first has ended, the folder is free again.
    OutputFolder third(out, {.is_previous = always});
    EXPECT_EQ(read_text_file(out / "a.txt"), "first\n");
}

TEST(OutputFolder, LeftoversOfKilledRunsAreRemoved) {
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    fs::create_directory(out);
    write_text_file(out / "a.txt", "complete\n");
    // A run killed while writing (pid 999999 is gone), one killed after its exchange, and a
    // lock file left by kill -9 (free: nobody holds it).
    fs::create_directories(dir / ".out.tmp-999999-0" / "sheets");
    fs::create_directories(dir / ".out.old-999999-1");
    write_text_file(dir / ".out.lock", "999999\n");
    // Names that are not ours are left alone.
    fs::create_directories(dir / ".out.tmp-notes");
    fs::create_directories(dir / ".out.tmp-1.tmp-2-3");
    {
        OutputFolder folder(out, {.is_previous = always});
        EXPECT_EQ(folder.recovered().size(), 2u);
        for (const std::string& line : folder.recovered()) EXPECT_NE(line.find("left by a killed run"), std::string::npos) << line;
    }
    EXPECT_EQ(read_text_file(out / "a.txt"), "complete\n");
    EXPECT_EQ(names(dir.path()), (std::vector<std::string>{".out.tmp-1.tmp-2-3", ".out.tmp-notes", "out"}));
}

TEST(OutputFolder, AKillBetweenTheTwoRenamesIsUndoneByTheNextRun) {
    // What the two-rename path leaves when killed between its renames: no OUT, the previous
    // result in .out.old-*, the new one in .out.tmp-*.
    const test::TempDir dir("outdir");
    const fs::path out = dir / "out";
    fs::create_directory(dir / ".out.old-4242-0");
    write_text_file(dir / ".out.old-4242-0" / "a.txt", "previous\n");
    fs::create_directory(dir / ".out.tmp-4242-0");
    write_text_file(dir / ".out.tmp-4242-0" / "a.txt", "new\n");
    {
        OutputFolder folder(out, {.is_previous = always});
        ASSERT_FALSE(folder.recovered().empty());
        EXPECT_NE(folder.recovered().front().find("restored " + out.string() + " from"), std::string::npos);
        EXPECT_EQ(read_text_file(out / "a.txt"), "previous\n"); // back before this run does anything
    }
    EXPECT_EQ(names(dir.path()), std::vector<std::string>{"out"});
    EXPECT_EQ(read_text_file(out / "a.txt"), "previous\n");
}

} // namespace
} // namespace specula

namespace specula {
namespace {

// A file named without a folder ("--json out.json") has an empty parent: the current folder,
// not an error.
TEST(FileUtil, PathsRelativeToTheCurrentFolder) {
    EXPECT_EQ(path_relative_to("captures/can", ""), "captures/can");
    EXPECT_EQ(path_relative_to("", "captures"), "..");
    EXPECT_EQ(path_relative_to("a/../b/", "b"), ".");
    EXPECT_EQ(folder_name(""), std::filesystem::current_path().filename().string());
    EXPECT_EQ(folder_name("captures/can/"), "can");
}

} // namespace
} // namespace specula
