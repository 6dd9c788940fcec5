#pragma once
// Output folders that never lie (issue 21): a command that writes a folder OUT (reconstruct,
// synth, evaluate --sheets) writes it whole into a staging folder beside OUT and renames it
// into place only once complete, so OUT holds either the previous complete result or the new
// complete one, whatever happens to the process in between (kill -9, a full disk, an error).
//
// Names beside OUT (same parent, so every rename stays on one file system):
//   .NAME.lock             the lock: flock(2) held for the whole run; a second run on the same
//                          OUT is refused while the first holds it. Removed at the end.
//   .NAME.tmp-<pid>-<n>    the staging folder the run writes into.
//   .NAME.old-<pid>-<n>    the previous OUT, only between the two renames of the fallback below.
// Replacing an existing OUT: one renameat2(RENAME_EXCHANGE) swaps the staging folder and OUT
// atomically (ext4, XFS, btrfs, tmpfs; OUT never disappears), then the staging name, which now
// holds the previous result, is removed. Where the file system has no exchange, OUT is renamed
// to .NAME.old-*, the staging folder to OUT, and the old one removed: a crash between those two
// renames leaves no OUT, the previous result complete in .NAME.old-* and the new one complete
// in .NAME.tmp-*; the next run on OUT (holding the lock) renames .NAME.old-* back to OUT.
// A run killed at any other point leaves a stale .NAME.tmp-* (and .NAME.lock): the next run,
// once it holds the lock, knows no other run is writing OUT and removes them.
// Durability across a power cut (fsync) is not attempted: the guarantee is against the
// process dying, not the machine.
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace specula {

struct OutputFolderOptions {
    /// The option that named OUT, for messages ("--out", "--sheets").
    std::string option = "--out";
    /// Replace an existing non-empty OUT that `is_previous` does not recognise.
    bool force = false;
    /// Recognises an earlier result of the same command in an existing, non-empty OUT (e.g.
    /// reconstruct's report.json); such an OUT is replaced without `force`. Unset: every
    /// non-empty OUT needs `force`, since replacing it deletes what it holds.
    std::function<bool(const std::filesystem::path& out)> is_previous;
    /// What the run reads (files or folders): OUT may neither be nor contain any of them,
    /// since replacing OUT would delete them.
    std::vector<std::filesystem::path> inputs;
    /// Replace an existing OUT with one renameat2(RENAME_EXCHANGE) where the file system has
    /// it; false takes the two-rename path (the tests reach it this way).
    bool exchange = true;
};

/// The absolute, lexically normal form of OUT ("dir/" names dir).
[[nodiscard]] std::filesystem::path output_folder_path(const std::filesystem::path& out);

/// One run's hold on an output folder. The constructor does every check before the caller
/// starts work: OUT is not a file or a device, does not contain the inputs, is not a
/// non-empty folder it may not replace, can be created (its parent folder is made and
/// writable), and no other run holds its lock. Refusals: UsageError for what the command line
/// asked (OUT a file, OUT holding the inputs, a non-empty OUT without force), InputError(OUT,
/// option, why) for what the file system refuses (a read-only mount, a path under a regular
/// file, no permission) and for OUT locked by another run (naming OUT and that run's pid).
/// Then it recovers what earlier killed runs left (see the header comment) and makes the
/// staging folder. commit() moves the staging folder into place; a destructor without
/// commit() removes it, leaving OUT as it was. The lock is released by the destructor.
class OutputFolder {
public:
    explicit OutputFolder(const std::filesystem::path& out, OutputFolderOptions options = {});
    ~OutputFolder();
    OutputFolder(const OutputFolder&) = delete;
    OutputFolder& operator=(const OutputFolder&) = delete;

    /// OUT, absolute and normal.
    [[nodiscard]] const std::filesystem::path& path() const noexcept { return m_out; }
    /// The folder to write into (empty, made by the constructor).
    [[nodiscard]] const std::filesystem::path& staging() const noexcept { return m_staging; }
    /// What the constructor recovered or removed of earlier runs, one line each (for the log).
    [[nodiscard]] const std::vector<std::string>& recovered() const noexcept { return m_recovered; }

    /// Moves the staging folder into place as OUT (replacing the previous OUT). Throws
    /// InputError when a rename fails; OUT is then the previous result (or absent if there
    /// was none). Call once.
    void commit();

private:
    void lock();
    void unlock() noexcept;
    void recover();

    std::filesystem::path m_out;
    std::filesystem::path m_staging;
    std::filesystem::path m_lock_path;
    std::string m_tag; ///< "<pid>-<n>" of the staging folder
    OutputFolderOptions m_options;
    std::vector<std::string> m_recovered;
    int m_lock_fd = -1;
    bool m_committed = false;
};

/// OutputFolder(out, options), write(staging), commit(): the folder is replaced only once
/// `write` returned; when it throws, OUT is left as it was and the exception propagates.
/// Returns OUT (absolute).
std::filesystem::path write_folder_atomically(const std::filesystem::path& out, const OutputFolderOptions& options,
                                              const std::function<void(const std::filesystem::path& staging)>& write);

} // namespace specula
