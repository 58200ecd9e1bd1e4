// A prior beside the current study: a second study (its own loading and spectrum) shown in
// view 2, turned with view 1 as the same view of the patient (each volume's own index frame),
// with view 1's kernel, size and window.
#include <fvr/ui/main_window.h>

#include <QFileDialog>
#include <QSettings>

#include <fvr/core/xray/patient_views.h>
#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

bool MainWindow::hasPrior() const {
    return m_prior && m_prior->volume() && m_prior->spectrum() && m_views.size() >= 2;
}

void MainWindow::openPrior(const StudySource& source) {
    if (!m_study->volume()) {
        message(tr("Open prior: open the current study first"), true);
        return;
    }
    if (!m_prior) {
        m_prior = std::make_unique<StudyController>();
        connect(m_prior.get(), &StudyController::studyLoaded, this,
                [this](const QString& name) { message(tr("Prior opened: %1").arg(name)); });
        connect(m_prior.get(), &StudyController::spectrumReady, this, [this] {
            if (m_prior->newerJobStarted()) return;
            if (m_difference) setDifferenceMode(false); // two studies do not subtract
            if (m_compareCount < 2) setCompareCount(2);
            assignSpectra();
            emit priorReady();
        });
        connect(m_prior.get(), &StudyController::failed, this,
                [this](const QString& title, const QString& details) {
                    message(tr("Prior: %1: %2").arg(title, details), true);
                });
        connect(m_prior.get(), &StudyController::seriesChoiceNeeded, this,
                [this](const StudySource& src, const QStringList& keys, const QStringList& labels,
                       const QString&) {
                    // The prior's default series, as fvr-render would open it.
                    message(tr("Prior %1 holds several series: opening the default one (%2)")
                                .arg(src.path, labels.first()));
                    StudySource chosen = src;
                    chosen.seriesKey = keys.first();
                    m_prior->open(chosen);
                });
    }
    // View 1's spectrum settings: the same kernel, values and correction, like with like.
    m_prior->setSpectrumSettings(m_study->spectrumSettings());
    message(
        tr("Opening prior %1…")
            .arg(source.kind == StudySource::Kind::Phantom ? source.displayName() : source.path));
    m_prior->open(source);
}

void MainWindow::closePrior() {
    if (!m_prior) return;
    m_prior.reset();
    if (m_views.size() >= 2) {
        m_views[1]->setTitle(viewTitle(1, m_viewSettings[1]));
        m_views[1]->setViewFrame(m_views[0]->viewFrame());
    }
    assignSpectra();
    message(tr("Prior closed"));
}

bool MainWindow::assignPrior() {
    if (!hasPrior()) return false;
    ProjectionView* v = m_views[1];
    ViewSettings s = m_viewSettings[0];
    v->setSettings(s);
    v->setStudy(m_prior->volume(), m_prior->spectrum());
    v->setPendingText({});
    v->setTitle(tr("Prior: %1").arg(m_prior->title()));
    v->setViewFrame(
        core::transferViewFrame(*m_study->volume(), *m_prior->volume(), m_views[0]->viewFrame()));
    return true;
}

core::ViewFrame MainWindow::linkedFrame(const ProjectionView* from, const ProjectionView* to,
                                        const core::ViewFrame& frame) const {
    // The same view of the patient where the two show different volumes (a prior).
    if (from->volume() && to->volume() && from->volume() != to->volume())
        return core::transferViewFrame(*from->volume(), *to->volume(), frame);
    return frame;
}

void MainWindow::openPriorDialog() {
    const QString path = QFileDialog::getExistingDirectory(
        this, tr("Open prior (DICOM folder)"), QSettings().value(keys::kLastFolder).toString());
    if (!path.isEmpty()) openPrior(StudySource::fromPath(path));
}

} // namespace fvr::ui
