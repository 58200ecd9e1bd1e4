#pragma once
/** The workstation driven from the command line (documentation, checks): once the study is open
 *  and every view shows its full-quality frame, writes each view's float projection (.npy), the
 *  image it displays without the overlay (.png), a views.json describing them and a screenshot
 *  of the whole window; then, with `quit`, ends the application (exit code 0). A study that
 *  fails to open prints "fvr-workstation: <message>" on stderr (exit code 1 with `quit`); a run
 *  that is not ready within the timeout says so (exit code 3 with `quit`). */
#include <QObject>
#include <QString>
#include <QTimer>

#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace fvr::ui {

class MainWindow;
class ProjectionView;

struct ScriptedRunOptions {
    QString exportDir; ///< DIR/view1.npy, view1.png, …, views.json (empty: none)
    QString screenshotFile; ///< the whole window as PNG (empty: none)
    bool quit = false; ///< end the application once written (or on failure)
    int timeoutSeconds = 600; ///< not ready by then: a message (and exit code 3 with quit)
    /** Whether anything is asked for (else no ScriptedRun is needed). */
    bool active() const { return quit || !exportDir.isEmpty() || !screenshotFile.isEmpty(); }
};

/** Exit codes of a scripted run with --quit. */
enum ScriptedExit : int { kScriptedOk = 0, kScriptedFailed = 1, kScriptedTimeout = 3 };

class ScriptedRun : public QObject {
    Q_OBJECT
public:
    /** Watches `window` from now on: construct it before MainWindow::openStudy. With `quit`,
     *  the timeout holds whatever the application is doing: at the timeout the process ends
     *  with kScriptedTimeout without waiting for a load that does not return, and a watchdog
     *  thread ends it kWatchdogGraceSeconds later if the GUI thread itself is blocked. */
    ScriptedRun(MainWindow& window, ScriptedRunOptions options, QObject* parent = nullptr);
    ~ScriptedRun() override;
    static constexpr int kWatchdogGraceSeconds = 5;

    /** Writes the exports of the views as they are now (throws core::WriteError naming the
     *  file); what the run does once ready. */
    void writeOutputs();
    /** Why a view cannot show its image (empty: none). */
    QString viewFailure() const;
    bool finished() const { return m_finished; }

signals:
    /** The run ended: kScriptedOk after writing, else the code and the message (also printed). */
    void done(int exitCode, const QString& message);

private:
    void onSpectrumReady();
    void poll();
    /** The last started preprocessing is in use and every view shows a full-quality frame
     *  rendered after it. */
    bool ready();
    void writeViews(const QString& dir);
    void finish(int exitCode, const QString& message);
    /** The watchdog thread's body: ends the process at the deadline unless the run finished. */
    void watch(int seconds);

    MainWindow& m_window;
    ScriptedRunOptions m_options;
    QTimer m_poll;
    QTimer m_timeout;
    bool m_armed = false; ///< a spectrum arrived
    int m_readyTicks = 0;
    bool m_finished = false;
    std::mutex m_watchMutex;
    std::condition_variable m_watchWake;
    bool m_watchStop = false;
    std::thread m_watchdog;
};

} // namespace fvr::ui
