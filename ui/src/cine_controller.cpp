// Cine playback: a timer turns the views by a step per tick.
#include <fvr/ui/cine_controller.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fvr::ui {

int CineSettings::framesPerTurn() const {
    const double step = std::abs(stepDegrees);
    return step > 0.0 ? std::max(1, int(std::lround(360.0 / step))) : 1;
}

const char* CineSettings::axisName() const {
    switch (axis) {
    case Axis::LeftRight: return "patient L-R";
    case Axis::AnteriorPosterior: return "patient A-P";
    case Axis::SuperiorInferior: break;
    }
    return "patient S-I";
}

CineController::CineController(std::function<std::optional<core::ViewFrame>()> current,
                               std::function<void(const core::ViewFrame&)> apply,
                               std::function<std::optional<core::Vec3>(CineSettings::Axis)> axisOf,
                               QObject* parent)
    : QObject(parent), m_current(std::move(current)), m_apply(std::move(apply)),
      m_axisOf(std::move(axisOf)) {
    m_timer.setTimerType(Qt::PreciseTimer);
    connect(&m_timer, &QTimer::timeout, this, &CineController::step);
    setSettings(m_settings);
}

void CineController::setSettings(const CineSettings& s) {
    m_settings = s;
    m_settings.fps = std::clamp(s.fps, 0.1, 120.0);
    m_timer.setInterval(std::max(1, int(std::lround(1000.0 / m_settings.fps))));
}

void CineController::play() {
    if (playing() || !m_current()) return;
    m_ticks = 0;
    m_timer.start();
    emit playingChanged(true);
}

void CineController::pause() {
    if (!playing()) return;
    m_timer.stop();
    emit playingChanged(false);
}

std::optional<core::ViewFrame> CineController::frameAt(const core::ViewFrame& start, int k) const {
    const auto axis = m_axisOf(m_settings.axis);
    if (!axis) return std::nullopt;
    return start.rotated(*axis, k * m_settings.stepDegrees * std::numbers::pi / 180.0);
}

void CineController::step() {
    const auto now = m_current();
    const auto next = now ? frameAt(*now, 1) : std::nullopt;
    if (!next) { // the study went: nothing to turn
        pause();
        return;
    }
    m_apply(*next);
    ++m_ticks;
    emit stepped(*next);
    if (!m_settings.loop && m_ticks >= m_settings.framesPerTurn()) pause();
}

} // namespace fvr::ui
