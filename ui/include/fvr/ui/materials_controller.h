#pragma once
/** The polychromatic output's material spectra (air, soft tissue, bone) of the open study's
 *  volume, prepared in the background (BackgroundJobs) once per volume and gridding correction,
 *  with cancel; modelled on StudyController. All signals arrive on the GUI thread. */
#include <QObject>
#include <QString>

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/volume.h>
#include <fvr/ui/background_job.h>

namespace fvr::ui {

class MaterialsController : public QObject {
    Q_OBJECT
public:
    using MaterialSpectra = std::vector<std::shared_ptr<const core::Spectrum>>;
    /** The key of a gridding correction: -1 none, else the kernel the spectra are deapodized
     *  for (each view renders the spectra of its kernel's key). */
    static int keyFor(const std::optional<core::Kernel>& deapodizeFor) {
        return deapodizeFor ? int(*deapodizeFor) : -1;
    }

    explicit MaterialsController(QObject* parent = nullptr);
    ~MaterialsController() override; ///< cancels the running job and waits for it

    /** The volume whose materials are wanted. Another volume than volume(): its spectra are
     *  dropped and a running job (the old volume's) is cancelled; returns true then. */
    bool setVolume(std::shared_ptr<const core::Volume> volume);
    std::shared_ptr<const core::Volume> volume() const { return m_volume; }
    /** Prepares the spectra of `keys` for volume() with `options`' transform and oversampling
     *  (one job at a time: nothing while busy()). Ends with ready(), discarded() or failed(). */
    void prepare(const std::set<int>& keys, const core::PreprocessOptions& options);
    /** A job was started and its end not handled yet. */
    bool busy() const { return m_busy; }
    const std::map<int, MaterialSpectra>& spectra() const { return m_spectra; }
    bool has(int key) const { return m_spectra.count(key) > 0; }
    /** Memory of all the spectra held, and their count. */
    double spectraMiB() const;
    int spectrumCount() const;

signals:
    /** New spectra of volume() are in spectra(). */
    void ready();
    /** The job ended without spectra for volume() (cancelled, or another volume came while it
     *  ran): ask again. */
    void discarded();
    void failed(const QString& error);

private:
    std::shared_ptr<const core::Volume> m_volume;
    std::map<int, MaterialSpectra> m_spectra;
    std::shared_ptr<core::CancelToken> m_cancel;
    bool m_busy = false;
    BackgroundJobs m_jobs{this}; ///< last: the job ends before the rest goes
};

} // namespace fvr::ui
