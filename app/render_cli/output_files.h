#pragma once
/**
 * fvr-render's outputs land all together or not at all. Every file of a run (the image or the
 * stack, a sweep's numbered frames, the sidecar FILE.json, --material-out) is written into a
 * staging folder beside FILE, `.NAME.PID-ID.N.part` (core::temporaryPathFor), and moved under its
 * final name only when all of them are complete: an interrupted run, a write error or a full disk
 * leaves the earlier run's files as they were, never a mix of two runs, never an image without its
 * sidecar.
 *
 * The commit first removes what the earlier run into FILE wrote and this one does not (its
 * sidecar FILE.json, then the files it lists that are FILE or FILE_NNNN.ext: a 200-view sweep
 * after a 500-view one leaves no view 200..499 behind), then moves the new files, the sidecar
 * last: a sidecar beside the frames always describes them.
 *
 * The leftovers of a run that died (kill -9, a crash, power loss) are removed by the next run
 * into the same folder: temporaries `.NAME.PID-ID.N.part` of outputs NAME (files or folders,
 * fvr's own form; the older `.NAME.PID.N.part` too) whose process is gone. ID is the writer's
 * host and pid namespace (core::writerIdentity): a temporary of another host or container
 * sharing the folder is never removed, its pid says nothing here. And the older form `FILE.part` of
 * this FILE's own names when no process has it open.
 */
#include <atomic>
#include <csignal>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace fvr::cli {

/** `name`'s temporary name in this process, `.NAME.PID-ID.N.part` (core::temporaryPathFor). */
std::string temporaryName(const std::string& name);

/** The NAME and PID of a temporary name `.NAME.PID-ID.N.part` of this pid space (ID ours) or
 *  `.NAME.PID.N.part`, or nothing (another host's or container's temporary among them). */
std::optional<std::pair<std::string, long>> parseTemporaryName(const std::string& filename);

/** Whether no process `pid` exists (kill(pid, 0) gives ESRCH); false where it may be alive. */
bool processIsGone(long pid);

/** Removes from `dir` the leftovers of runs that died: fvr's temporaries of outputs (.npy,
 *  .pfm, .png, .dcm, .json, .zarr) whose process is gone, and `out`'s own old-form temporaries
 *  (FILE.part, FILE.json.part, FILE_NNNN.ext.part) that no process has open and that have not
 *  changed for a minute. Returns the names removed; never throws. */
std::vector<std::string> removeStaleTemporaries(const std::filesystem::path& dir,
                                                const std::string& out);

/** Removes from `dir` the temporaries `.NAME.PID-ID.N.part` of `name` alone (files or folders)
 *  whose process is gone (ID ours, or none); never throws. */
void removeStaleTemporariesOf(const std::filesystem::path& dir, const std::string& name);

/** Whether `name` (a file name) is one of the frames --out `out` writes: STEM_NNNN.ext. */
bool isNumberedFrame(const std::string& name, const std::string& out);

/** The files of one --out run: staged, then committed together (see the file comment). */
class OutputFiles {
public:
    /** Removes the folder's stale temporaries and creates the staging folder; WriteError naming
     *  `out` and the reason where the folder cannot be written. */
    explicit OutputFiles(std::string out);
    /** Without a commit: removes every staged file (the final names untouched). */
    ~OutputFiles();
    OutputFiles(const OutputFiles&) = delete;
    OutputFiles& operator=(const OutputFiles&) = delete;

    /** Where the file to land at `finalPath` is written now (in the staging folder, or beside
     *  it under a temporary name for a file in another folder). */
    std::filesystem::path staged(const std::string& finalPath);
    /** `message` with the staged paths written as their final paths (the user's names). */
    std::string finalNames(std::string message) const;
    /** Removes the earlier run's files, moves every staged file into place (FILE.json last).
     *  WriteError naming the file where one cannot be moved. */
    void commit();

private:
    void removeEarlierRun() const;
    void discard() noexcept;

    std::string m_out;
    std::filesystem::path m_dir, m_staging;
    std::vector<std::pair<std::filesystem::path, std::filesystem::path>> m_files; // staged, final
};

/** Thrown by a render loop when SIGINT, SIGTERM or SIGHUP came: unwinds the writers (the staged
 *  files removed) before InterruptGuard dies of the signal. */
struct Interrupted : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/**
 * SIGINT, SIGTERM and SIGHUP (a closed terminal) while the views are rendered and written set a
 * flag that the render loop checks after each view, so that an interrupted run removes its
 * unfinished files, then dies of the signal as it would have (a shell or make sees the signal).
 * Only where the signal had its default action (a background job's ignored SIGINT stays
 * ignored, nohup's SIGHUP too); one-shot (SA_RESETHAND), so that a second signal ends the run at
 * once.
 */
class InterruptGuard {
public:
    InterruptGuard();
    ~InterruptGuard() { restore(); }
    InterruptGuard(const InterruptGuard&) = delete;
    InterruptGuard& operator=(const InterruptGuard&) = delete;

    /** The signal that came, or 0. */
    static int signal() { return s_signal; }
    /** Where a signal came: says `what` and dies of the signal. */
    void dieIfInterrupted(const std::string& what);

private:
    static void onSignal(int sig) { s_signal = sig; }
    void restore();

    static constexpr int kSignals[3] = {SIGINT, SIGTERM, SIGHUP};
    static inline std::atomic<int> s_signal{0}; // lock-free: set by the handler on any thread
    bool m_installed[3] = {};
};

} // namespace fvr::cli
