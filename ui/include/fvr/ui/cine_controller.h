#pragma once
/** Cine: the views turn by a step per tick at a frame rate, about one of the patient's axes
 *  (S-I by default), looping or for one full 360° turn. The frames go through the views' normal
 *  rendering path; the controller only moves the camera. */
#include <QObject>
#include <QTimer>

#include <functional>
#include <optional>

#include <fvr/core/render/view.h>

namespace fvr::ui {

struct CineSettings {
    /** The patient axis turned about: head-feet (S-I), left-right (L-R), front-back (A-P). */
    enum class Axis { SuperiorInferior, LeftRight, AnteriorPosterior };
    Axis axis = Axis::SuperiorInferior;
    double stepDegrees = 5.0; ///< per frame; negative turns the other way
    double fps = 15.0; ///< frames (ticks) per second
    bool loop = true; ///< false: one full turn, then it stops where it started
    /** Frames of one full turn: 360 / |step|, rounded (at least 1). */
    int framesPerTurn() const;
    /** The axis in words ("patient S-I"). */
    const char* axisName() const;
};

class CineController : public QObject {
    Q_OBJECT
public:
    /** `current`: the view frame on screen (none without a study); `apply`: shows a frame on
     *  every view; `axisOf`: the patient axis in the volume's index frame (none without a
     *  study). */
    CineController(std::function<std::optional<core::ViewFrame>()> current,
                   std::function<void(const core::ViewFrame&)> apply,
                   std::function<std::optional<core::Vec3>(CineSettings::Axis)> axisOf,
                   QObject* parent = nullptr);

    const CineSettings& settings() const { return m_settings; }
    /** New settings apply from the next tick (the rate at once). */
    void setSettings(const CineSettings& s);
    bool playing() const { return m_timer.isActive(); }
    void play();
    void pause();
    void toggle() { playing() ? pause() : play(); }
    /** One step (what each tick does): the view turns by the step about the axis. */
    void step();
    /** Ticks since play() (a one-turn cine stops after framesPerTurn()). */
    int ticks() const { return m_ticks; }
    /** Frame `k` of a cine from `start`: `start` turned by k x step about the axis. */
    std::optional<core::ViewFrame> frameAt(const core::ViewFrame& start, int k) const;

signals:
    void playingChanged(bool playing);
    void stepped(const core::ViewFrame& frame);

private:
    CineSettings m_settings;
    QTimer m_timer;
    int m_ticks = 0;
    std::function<std::optional<core::ViewFrame>()> m_current;
    std::function<void(const core::ViewFrame&)> m_apply;
    std::function<std::optional<core::Vec3>(CineSettings::Axis)> m_axisOf;
};

} // namespace fvr::ui
