#pragma once
// fvr-workstation's command line: the study to open, the views to start with, and the scripted
// exports (documentation, checks).
#include <QSize>
#include <QString>

#include <optional>
#include <vector>

#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/ui/scripted_run.h>
#include <fvr/ui/study.h>
#include <fvr/ui/view_settings.h>

class QCoreApplication;

namespace fvr::ui {
class MainWindow;
}

namespace fvr::app {

struct WorkstationOptions {
    ui::StudySource source; ///< the built-in phantom when no study is named
    int compare = 1;
    std::optional<core::PatientView> view;
    std::vector<core::Kernel> kernels; ///< view 1's, 2's … (fewer: the others keep theirs)
    std::vector<core::VoxelModel> voxelModels; ///< view 1's, 2's …; the last for the rest
    std::optional<int> size; ///< every view's
    /** The views' projections in order (the last for the rest): parallel or cone. */
    std::vector<ui::ProjectionKind> projections;
    std::optional<std::pair<double, double>> carm; ///< --carm PRIMARY,SECONDARY (degrees)
    std::optional<double> sid, sod; ///< mm
    std::optional<core::RayModel> rayModel;
    /** --open-session FILE: a saved session instead of a study (Qt itself takes --session, for
     *  X11 session management). */
    QString session;
    QString matchXray; ///< --match-xray FILE: File ▸ Open X-ray to match… once the study is open
    std::optional<QSize> windowSize;
    ui::ScriptedRunOptions script;
};

/** Parses the command line (--help and --version print and exit, as QCommandLineParser does:
 *  main parses them before any display is opened, so that they need none);
 *  throws core::SettingsError naming the option for a bad value. */
WorkstationOptions parseWorkstationOptions(const QCoreApplication& app);

/** Applies the views' options to a shown window before its study opens: compare count, view 1's
 *  kernel and every view's size (through the Rendering panel, as a user would: the startup settings
 * follow), the patient view once the study is loaded, the window size. */
void applyWorkstationOptions(ui::MainWindow& window, const WorkstationOptions& o);

} // namespace fvr::app
