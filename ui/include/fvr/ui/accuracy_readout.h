#pragma once
/** The accuracy readout: a view's projection against the spatial (ray-casting) projector of the
 *  same voxels and view, computed on a worker thread; the results arrive on the GUI thread. */
#include <QObject>

#include <fvr/ui/background_job.h>

namespace fvr::ui {

class ProjectionView;
class StudyController;

class AccuracyReadout : public QObject {
    Q_OBJECT
public:
    explicit AccuracyReadout(QObject* parent = nullptr);
    ~AccuracyReadout() override;

    /** Starts measuring `view` (nothing without a study or a projection; a message while the
     *  previous measurement runs, when slice filters are on, or for a polychromatic view: the
     *  ray caster makes line integrals, not -ln(I/I0) or a material's mass thickness). */
    void measure(ProjectionView& view, const StudyController& study);

signals:
    /** What to tell the user (the start, the result or why nothing was measured). */
    void message(const QString& text, bool error);
    void measured(double psnr, double relRmse);

private:
    BackgroundJobs m_jobs{this}; ///< last: the measurement ends before the rest goes
};

} // namespace fvr::ui
