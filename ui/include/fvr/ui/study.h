#pragma once
/** The open study and its preprocessing, run in the background with progress and cancel. All
 *  signals arrive on the GUI thread. */
#include <QObject>
#include <QString>
#include <QStringList>
#include <QTimer>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string_view>
#include <thread>
#include <vector>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/io/open_study.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/volume.h>
#include <fvr/ui/background_job.h>

namespace fvr::ui {

/** Where a study comes from: the built-in phantom, a volume file, a DICOM file or a DICOM
 *  folder/series. What a path names follows core::classifyInput, as in fvr-render. */
struct StudySource {
    enum class Kind { Phantom, VolumeFile, DicomFolder, DicomFile };
    Kind kind = Kind::Phantom;
    QString path; ///< file or folder (a DICOMDIR: its folder)
    QString seriesKey; ///< DICOM series (empty: the only one, or the user is asked)
    int phantomSize = 128;
    core::PhantomKind phantomKind = core::PhantomKind::SheppLogan;

    QString displayName() const;
    /** The built-in Shepp-Logan phantom (tests: small and quick). */
    static StudySource phantom(int n = 128);
    /** The built-in chest phantom: the first study, a radiograph's anatomy. */
    static StudySource chest(int n = 160);
    /** By core::classifyInput ("phantom:chest[:N]" and "phantom:shepp-logan[:N]" included). A path
     * that cannot be classified (missing) keeps it as given; opening it then reports the error. */
    static StudySource fromPath(const QString& path);
    core::InputSource toCore() const;
};

/** Preprocessing settings that need a new spectrum when they change: core's options, with the
 *  workstation's defaults from workstationSpectrumDefaults(). */
using SpectrumSettings = core::PreprocessOptions;
/** The Rendering panel's default values' spectrum (attenuation, FFT, oversampling 1.25,
 *  gridding correction for Kaiser-Bessel 4): the controller's settings until the window sets its
 * own. */
SpectrumSettings workstationSpectrumDefaults();

/** A DICOM person name as the panels, the title and the PACS dialog show it: the components
 *  ("DOE^JOHN") separated by spaces ("DOE JOHN"). */
QString personName(const std::string& dicomName);
/** A DICOM date as the panels and the PACS dialog show it: "20150206" as "2015-02-06"; what is
 *  not a calendar day YYYYMMDD (empty, "2015", "20231301") as it is. */
QString dicomDate(const std::string& date);
/** A count with its noun in the singular or the plural: countOf(1, tr("1 image"),
 *  tr("%1 images")) is "1 image", with 93 "93 images" (never "image(s)"). */
QString countOf(int n, const QString& one, const QString& many);

class StudyController : public QObject {
    Q_OBJECT
public:
    explicit StudyController(QObject* parent = nullptr);
    ~StudyController() override;

    /** Loads a study (worker thread), then preprocesses it with the current settings. */
    void open(const StudySource& source);
    /** Records the user's settings and re-runs preprocessing when the settings that follow
     *  from them for this study differ from the current spectrum's. A mapping equal to the one
     *  in effect (say raw, forced by an MR study) keeps the request (say attenuation) for the
     *  next study. */
    void setSpectrumSettings(const SpectrumSettings& settings);
    /** Cancels the running load or preprocessing; the previous study stays usable. */
    void cancel();
    bool busy() const { return m_jobs.running(); }
    /** Cancel was asked of the running job, which has not stopped yet (FFTW's planner, for one,
     *  cannot be interrupted: it ends its plan first). */
    bool cancelling() const { return busy() && m_cancel && m_cancel->cancelled(); }
    /** In a spectrumReady handler: a job started after the one whose result this is (its own
     *  progress and result follow). Exact on the GUI thread, unlike busy(), which races with
     *  the worker's last instructions. */
    bool newerJobStarted() const { return m_jobsStarted != m_resultJob; }

    std::shared_ptr<const core::Volume> volume() const { return m_volume; }
    std::shared_ptr<const core::Spectrum> spectrum() const { return m_spectrum; }
    /** The settings of the spectrum in use (the values adjusted to the study: raw for data
     *  that are not Hounsfield units). */
    const SpectrumSettings& spectrumSettings() const { return m_settings; }
    /** What the user asked for: the next study opens with these (values follow the user, not
     *  the previous study's adjustment). */
    const SpectrumSettings& requestedSettings() const { return m_requested; }
    /** The settings the spectrum will have once the running job ends (those in use when none
     *  runs). */
    const SpectrumSettings& targetSettings() const { return m_target; }
    const StudySource& source() const { return m_source; }
    /** The DICOM series of the open study (patient, study date, modality, description); empty
     *  for volume files and the phantom. */
    const std::optional<core::DicomSeriesInfo>& series() const { return m_series; }
    /** The open study's name for the title bar: the series description and patient for DICOM,
     *  the file or phantom name otherwise. */
    QString title() const;
    const QStringList& warnings() const { return m_warnings; }
    /** Spectrum memory (MiB) the settings would need for the current volume. */
    double estimatedSpectrumMiB(const SpectrumSettings& s) const;

    /** Compare mode: the kernels of the other views, and whether gridding correction is on.
     *  A spectrum deapodized for one kernel cannot render another: each kernel gets the
     *  spectrum settingsFor() gives (its own gridding-corrected one where the kernel needs
     *  one), prepared in the background one after the other once no other job runs, each
     *  announced by spectrumReady(). Spectra of kernels no longer listed are freed. */
    void setCompareKernels(const std::vector<core::Kernel>& kernels, bool gridding,
                           bool retry = false);
    /** The spectrum that renders `kernel` at the settings in effect: the main spectrum, or a
     *  compare kernel's own; null while it is being prepared (or was cancelled). */
    std::shared_ptr<const core::Spectrum> spectrumFor(core::Kernel kernel) const;
    /** Why spectrumFor(kernel) is null: being prepared, or cancelled / out of memory. */
    QString spectrumPendingReason(core::Kernel kernel) const;
    /** Why a compare kernel's spectrum will not be prepared (cancelled, out of memory, an
     *  error) until setCompareKernels is called with `retry`; empty while it is wanted. */
    std::optional<QString> compareDeclined(core::Kernel kernel) const;
    /** The settings of the spectrum that renders `kernel`: the values, transform and
     *  oversampling in effect, deapodized for `kernel` when gridding correction is on and
     *  helps the kernel (core::griddingCorrectionHelps: all but linear). */
    SpectrumSettings settingsFor(core::Kernel kernel) const;
    /** Memory of the spectra in use (the main one and the compare kernels'), and their count. */
    double spectraMiB() const;
    int spectrumCount() const;
    /** Blocks until the running job ends (tests). */
    void waitIdle();
    /** Tests: every compare-spectrum job first waits this long (a slow machine), cancellable. */
    void setSimulatedCompareDelayMs(int ms) { m_simulatedCompareDelayMs = ms; }

    /** A series as the chooser lists it: patient, modality, date, the description (or, without
     *  one, "series N" and the slice count: never the raw UID), images and size. */
    static QString seriesChoiceLabel(const core::DicomSeriesInfo& s);
    /** The chooser's question: the folder and its patient; a warning naming them where the
     *  series belong to several patients. */
    static QString seriesChoicePrompt(const QString& folder, const core::DicomScanResult& scan);

signals:
    void progress(double fraction, const QString& stage);
    void studyLoaded(const QString& name);
    void spectrumReady();
    /** A load or preprocessing failed: `title` names what, `details` is the error text. */
    void failed(const QString& title, const QString& details);
    void cancelled();
    /** No job runs any more (every job's end was handled): nothing to show progress for. */
    void idle();
    void warningsChanged(const QStringList& warnings);
    /** A DICOM folder holds several series: the GUI asks the user and calls open() again with
     *  the chosen key. `labels` describe the series (same order as `keys`); the first is the
     *  default series (core::defaultSeriesIndex, what fvr-render opens), marked so. `prompt`
     *  names the folder and its patient, and warns where the folder mixes patients. */
    void seriesChoiceNeeded(const StudySource& source, const QStringList& keys,
                            const QStringList& labels, const QString& prompt);

private:
    /** The settings `requested` give for `volume` (raw values for data that are not HU, with
     *  the warning appended to `warnings`). */
    static SpectrumSettings settingsForStudy(const SpectrumSettings& requested,
                                             const core::Volume& volume, QStringList* warnings);
    /** After a cancel: the request goes back to what is in effect (GUI thread). */
    void revertRequestToSettingsInEffect();
    /** What a job hands to the GUI thread when it ends (run there; may be empty). */
    using GuiStep = std::function<void()>;
    /** A job's work on the worker thread, given its cancel token and its id. */
    using JobWork = std::function<GuiStep(core::CancelToken&, std::uint64_t)>;
    using JobFailed = std::function<void(const JobError&, std::uint64_t)>;
    /** Runs `work` on the worker thread, after cancelling and waiting for the running job; its
     *  GuiStep, or `failed` (jobFailed() when empty) with what it threw, on the GUI thread. */
    void startJob(JobWork work, JobFailed failed = {});
    /** A load's or preprocessing's error: cancelled by the user (the request goes back to what
     *  is in effect), out of memory, or failed. */
    void jobFailed(const JobError& e, std::uint64_t id);
    void poll();
    void preprocessAsync();
    void report(double fraction, std::string_view stage);
    /** Worker: the scan of a DICOM folder (cached for the series choice). */
    std::shared_ptr<const core::DicomScanResult> scanFolder(
        const StudySource& source, std::shared_ptr<const core::DicomScanResult> cached,
        core::CancelToken& token);
    /** Worker: the GUI step that asks to choose a series (the default first); empty when none
     *  is needed. */
    GuiStep seriesChoice(const StudySource& source, const core::DicomScanResult& scan,
                         std::uint64_t id);
    /** Starts the next missing compare spectrum when no job runs. */
    void prepareCompareSpectra();
    void startCompareJob(core::Kernel k);
    /** GUI thread: a compare job ended (with its spectrum, or `failure`). */
    void compareJobDone(std::uint64_t id, core::Kernel k,
                        const std::shared_ptr<const core::Volume>& vol,
                        const SpectrumSettings& settings,
                        std::shared_ptr<const core::Spectrum> spectrum, const QString& failure);
    /** A compare kernel still listed, at these settings, that the main spectrum does not serve. */
    bool wantedCompareSpectrum(core::Kernel kernel, const SpectrumSettings& settings) const;
    /** Drops compare spectra that no longer match the volume and the settings in effect. */
    void pruneCompareSpectra();
    /** Every compare kernel without a spectrum is not prepared, for `reason`. */
    void declinePendingCompare(const QString& reason);
    /** Worker: preprocesses the opened volume; the step hands volume and spectrum to the GUI. */
    GuiStep finishOpen(const StudySource& source, const SpectrumSettings& settings,
                       core::OpenedStudy opened, core::CancelToken& token, std::uint64_t id);

    StudySource m_source;
    SpectrumSettings m_settings = workstationSpectrumDefaults(); ///< in effect
    SpectrumSettings m_requested = workstationSpectrumDefaults(); ///< asked for
    SpectrumSettings m_target = workstationSpectrumDefaults(); ///< what the latest job gives
    std::shared_ptr<const core::Volume> m_volume;
    std::shared_ptr<const core::Spectrum> m_spectrum;
    QStringList m_warnings;
    std::optional<core::DicomSeriesInfo> m_series;
    std::uint64_t m_jobsStarted = 0; ///< GUI thread
    std::uint64_t m_resultJob = 0; ///< the job whose result is in use (GUI thread)
    std::uint64_t m_finishedJob = 0; ///< the latest job whose end was handled (GUI thread)
    /** A job's end was handled (GUI thread); once the handler has run (and maybe started the
     *  next job), idle() says so if no job runs. */
    void markFinished(std::uint64_t id);
    std::shared_ptr<core::CancelToken> m_cancel;
    std::atomic<double> m_fraction{0};
    QString m_stage;
    std::mutex m_stageMutex;
    QTimer m_timer;
    struct CompareSpectrum {
        SpectrumSettings settings;
        std::shared_ptr<const core::Volume> volume;
        std::shared_ptr<const core::Spectrum> spectrum;
    };
    std::atomic<int> m_simulatedCompareDelayMs{0};
    std::vector<core::Kernel> m_compareKernels;
    bool m_compareGridding = true;
    std::map<core::Kernel, CompareSpectrum> m_compare;
    std::map<core::Kernel, QString> m_compareDeclined; ///< cancelled or failed: not retried
    struct CompareJob {
        std::uint64_t id = 0;
        core::Kernel kernel = core::Kernel::Linear;
        SpectrumSettings settings;
        bool dropped = false; ///< cancelled because its spectrum is no longer wanted
        bool cancelledByUser = false;
    } m_compareJob;
    std::shared_ptr<const core::DicomScanResult> m_scan; ///< last DICOM scan (series picking)
    QString m_scanFolder;
    BackgroundJobs m_jobs{this}; ///< last: its jobs end before the members they use go
};

} // namespace fvr::ui
