#pragma once
/** What the workstation shows, as plain data: the render settings, each compare slot's own
 *  settings, the views' orientation, windows, zoom and pan. Undo/redo records it before and
 *  after each change (QUndoStack); a saved session is it with the study and the annotations.
 *  Saved as an INI file (QSettings) with the same keys and value names as the startup
 *  settings, so a session written by this version reads back exactly, and one written by a
 *  later version keeps the defaults for what it does not know. */
#include <QPointF>
#include <QString>

#include <array>
#include <vector>

#include <fvr/core/render/view.h>
#include <fvr/core/xray/display_window.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/view_settings.h>

class QSettings;

namespace fvr::ui {

struct StudySource;

/** One view on screen. */
struct ViewState {
    core::DisplayWindow window;
    double zoom = 1.0;
    QPointF pan;
};

struct WorkstationState {
    int compareCount = 1;
    bool difference = false;
    /** The compare slots' settings (slot 0: view 1); all four, so that leaving and returning
     *  to compare mode keeps them. */
    std::array<ViewSettings, 4> compareSlots;
    core::ViewFrame frame; ///< shared by the synchronised views
    std::vector<ViewState> views; ///< one per view on screen
    RenderingPanel::Values rendering;
    XrayPanel::Values xray;

    /** Equal up to rounding (1e-9 relative on the windows, 1e-9 on the frame): what undo and
     *  the session round trip compare. */
    bool sameAs(const WorkstationState& o) const;
    /** What differs from `before`, in a few words for the Edit menu ("Undo Window"). */
    QString changeFrom(const WorkstationState& before) const;
};

/** Writes the state into `s` (groups "workstation", "view1".."view4", and the panels' keys). */
void saveState(QSettings& s, const WorkstationState& state);
/** Reads what saveState() wrote; missing or unreadable keys keep `base`'s values. */
WorkstationState loadState(QSettings& s, WorkstationState base = {});

/** The study as a session names it: "phantom:chest:160", a file or folder, and its series. */
void saveStudySource(QSettings& s, const StudySource& source);
/** The session's study; throws core::SettingsError naming the problem when it has none. */
StudySource loadStudySource(const QSettings& s);

} // namespace fvr::ui
