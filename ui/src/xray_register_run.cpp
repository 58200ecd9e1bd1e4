// Register to X-ray…: the registration in the background, its progress and Cancel, and what
// follows it: the overlays before and after, Accept, Revert, Save pose (xray_register.h).
#include <fvr/ui/xray_register.h>

#include <QCheckBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QLabel>
#include <QPointer>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>

#include <fvr/ui/background_job.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/xray_match.h>

namespace fvr::ui {

namespace {

QString poseText(const core::Pose& p) {
    return QObject::tr("rx %1° ry %2° rz %3°, t (%4, %5, %6) mm")
        .arg(p.rotationDeg.x, 0, 'f', 2)
        .arg(p.rotationDeg.y, 0, 'f', 2)
        .arg(p.rotationDeg.z, 0, 'f', 2)
        .arg(p.translationMm.x, 0, 'f', 2)
        .arg(p.translationMm.y, 0, 'f', 2)
        .arg(p.translationMm.z, 0, 'f', 2);
}

} // namespace

void XrayRegisterDialog::setBusy(bool busy) {
    m_running = busy;
    const bool ready = m_input.has_value() && m_drr.has_value();
    for (QDoubleSpinBox* s : m_spins) s->setEnabled(!busy && ready);
    m_reset->setEnabled(!busy && ready);
    m_canvas->setInteractive(!busy && ready);
    m_register->setEnabled(!busy && ready);
    m_cancel->setEnabled(busy);
    // Accept and Revert: while a registered pose awaits the user's word.
    const bool pending = !busy && m_pending;
    m_accept->setEnabled(pending);
    m_revert->setEnabled(pending);
    showCaptions();
    m_save->setEnabled(!busy && ready);
}

void XrayRegisterDialog::startRegistration() {
    if (m_running || !m_input || !m_volume || !m_drr) return;
    m_before = m_pose;
    m_drrBeforeImage = grayImage(m_drr->pixels.data(), m_drr->width, m_drr->height, false);
    m_cancelFlag = std::make_shared<std::atomic<bool>>(false);
    core::RegistrationOptions o = m_options;
    o.centreSet = true;
    o.centre = m_centre;
    o.projector.mapping = m_mapping;
    o.cancel = m_cancelFlag.get();
    QPointer<XrayRegisterDialog> self(this);
    o.progress = [self](const core::RegistrationProgress& p) {
        postToGui(self, [self, p] { self->showProgress(p); });
    };
    const int levels = int(o.levels.size());
    emit message(tr("Registration to %1 started: %2 level(s), %3, from %4")
                     .arg(xrayName())
                     .arg(levels)
                     .arg(QString::fromLatin1(core::similarityName(o.similarity)))
                     .arg(poseText(m_pose)));
    m_progressText->setText(tr("Starting…"));
    m_progress->setRange(0, 0); // busy until the first progress report
    m_resultText->clear();
    setBusy(true);
    auto volume = m_volume;
    auto flag = m_cancelFlag;
    std::vector<core::RegistrationView> views{m_input->view};
    m_jobs->run(
        [volume, flag, views, init = m_pose, o](core::CancelToken& token) mutable {
            auto report = o.progress;
            // The jobs' own cancel (the dialog going) reaches the registration's flag too.
            o.progress = [&token, flag, report](const core::RegistrationProgress& p) {
                if (token.cancelled()) flag->store(true);
                report(p);
            };
            return core::registerPose(*volume, views, init, o);
        },
        [this](core::RegistrationResult r) { finishRegistration(std::move(r)); },
        [this](const JobError& e) { failRegistration(e.message, e.cancelled()); });
}

void XrayRegisterDialog::cancelRegistration() {
    if (!m_running || !m_cancelFlag) return;
    m_cancelFlag->store(true);
    m_progressText->setText(tr("Cancelling: the best pose so far follows…"));
}

void XrayRegisterDialog::showProgress(const core::RegistrationProgress& p) {
    if (!m_running) return;
    m_progress->setRange(0, std::max(1, p.maxEvaluations));
    m_progress->setValue(std::min(p.evaluations, std::max(1, p.maxEvaluations)));
    m_progressText->setText(tr("Stage %1 of %2 (%3): %4 of %5 evaluations, best similarity %6")
                                .arg(p.stageIndex + 1)
                                .arg(p.stageCount)
                                .arg(QString::fromStdString(p.stage))
                                .arg(p.evaluations)
                                .arg(p.maxEvaluations)
                                .arg(p.bestSimilarity, 0, 'f', 4));
    // The spin boxes (disabled meanwhile) follow the best pose so far; the DRR waits for the end.
    const core::Pose shown = m_pose;
    m_pose = p.bestPose;
    showPoseInSpins();
    m_pose = shown;
}

void XrayRegisterDialog::finishRegistration(core::RegistrationResult r) {
    m_result = std::move(r);
    const core::RegistrationResult& res = *m_result;
    m_progress->setRange(0, 1);
    m_progress->setValue(res.cancelled ? 0 : 1);
    m_progressText->setText(res.cancelled ? tr("Cancelled") : tr("Done"));
    m_beforeCanvas->show();
    m_pending = true;
    core::Pose found = res.pose;
    try { // the result's matrix about our centre (the same pose when its centre is ours)
        found = core::poseFromMatrix(res.matrix, m_centre);
    } catch (const std::exception&) {}
    setPose(found);
    const QString sims = tr("similarity (%1) %2 → %3 in %4 s, %5 evaluations")
                             .arg(QString::fromLatin1(core::similarityName(m_options.similarity)))
                             .arg(res.similarityBefore, 0, 'f', 4)
                             .arg(res.similarityAfter, 0, 'f', 4)
                             .arg(res.seconds, 0, 'f', 2)
                             .arg(res.evaluations);
    m_resultText->setText((res.cancelled ? tr("Cancelled: the best pose so far, ") : QString()) +
                          sims + '\n' + tr("Pose: %1").arg(poseText(m_pose)));
    setBusy(false);
    if (res.cancelled)
        emit message(tr("Registration to %1 cancelled after %2 s: the best pose so far, %3")
                         .arg(xrayName())
                         .arg(res.seconds, 0, 'f', 2)
                         .arg(poseText(m_pose)));
    else
        emit message(
            tr("Registration to %1 finished: %2; %3").arg(xrayName(), sims, poseText(m_pose)));
    emit registrationEnded();
}

void XrayRegisterDialog::failRegistration(const QString& why, bool cancelled) {
    m_progress->setRange(0, 1);
    m_progress->setValue(0);
    m_progressText->setText(cancelled ? tr("Cancelled") : tr("Failed: %1").arg(why));
    showPoseInSpins(); // the pose before Register, still shown
    setBusy(false);
    emit message(tr("Registration to %1 %2")
                     .arg(xrayName(), cancelled ? tr("cancelled") : tr("failed: %1").arg(why)),
                 !cancelled);
    emit registrationEnded();
}

void XrayRegisterDialog::acceptPose() {
    if (m_running || !m_result) return;
    m_before = m_pose;
    m_pending = false;
    m_beforeCanvas->hide();
    setBusy(false);
    emit message(tr("Registered pose accepted: %1").arg(poseText(m_pose)));
}

void XrayRegisterDialog::revert() {
    if (m_running || !m_result) return;
    m_pending = false;
    m_beforeCanvas->hide();
    setPose(m_before);
    setBusy(false);
    emit message(tr("Pose reverted to the one before Register: %1").arg(poseText(m_pose)));
}

bool XrayRegisterDialog::savePose(const QString& path) {
    try {
        core::writePoseJson(path.toStdString(), poseMatrix(), m_centre);
    } catch (const std::exception& e) {
        emit message(tr("Pose not saved: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    emit message(tr("Pose saved to %1 (about the centre (%2, %3, %4) mm)")
                     .arg(path)
                     .arg(m_centre.x, 0, 'f', 1)
                     .arg(m_centre.y, 0, 'f', 1)
                     .arg(m_centre.z, 0, 'f', 1));
    return true;
}

void XrayRegisterDialog::savePoseDialog() {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Save pose"), QSettings().value(keys::kLastFolder).toString() + "/pose.json",
        tr("Pose JSON (*.json);;All files (*)"));
    if (!path.isEmpty()) savePose(path);
}

} // namespace fvr::ui
