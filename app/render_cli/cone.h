#pragma once
/** fvr-render --geometry cone: the cameras (the C-arm options, --sweep and --orbit, or a
 *  projection-matrix file), their checks against the volume, the CPU ray caster
 *  (core::ConeProjector), --bench and --out. The images are written by the parallel views'
 *  writers (outputs.cpp), the sidecar by json_output's blocks. */
#include <optional>
#include <vector>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/dicom/rt_image.h>
#include <fvr/core/dicom/rt_plan.h>
#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/volume.h>

#include "backend.h"
#include "json_output.h"
#include "options.h"

namespace fvr::cli {

/** One cone-beam view: its camera, and the C-arm or the treatment beam that placed it (none
 *  from a matrix file). */
struct ConeView {
    core::ConeCamera camera;
    std::optional<core::CArm> arm;
    /** --beam (number 0, no name) or one beam of --rtplan. */
    std::optional<core::RtPlanBeam> beam;
};

/** The cameras of --projection-matrix (read before the input loads, so that its errors come
 *  first); empty without it. */
std::vector<core::ConeCamera> readConeMatrixFile(const Options& o);

/** The views of --beam or --rtplan's beams: the imager (--detector-size, --pitch, default
 *  core::framingPitch at SAD and SID) about each beam's isocentre (--beam: --isocenter, else
 *  the volume's centre). */
std::vector<ConeView> beamViews(const Options& o, const core::Volume& volume);

/** What the camera options name in files, read before the input loads (their errors first). */
struct ConeFiles {
    std::vector<core::ConeCamera> matrixCameras; ///< --projection-matrix
    std::optional<core::XrayGeometry> xray; ///< --geometry-from, without its pixels
};
/** Reads --projection-matrix and --geometry-from (cone_xray.cpp). */
ConeFiles readConeFiles(const Options& o);

/** --geometry-from (cone_xray.cpp): reads the X-ray's geometry, checks --frame against its
 *  frames and says each of its warnings on stderr; nothing without the option. */
std::optional<core::XrayGeometry> readConeXray(const Options& o);
/** The views of --geometry-from: the frame's (or every frame's) C-arm with the file's detector,
 *  pitch and principal offset, about the file's isocentre where it states one, else --isocenter,
 *  else the volume's centre. */
std::vector<ConeView> xrayViews(const Options& o, const core::Volume& volume,
                                const core::XrayGeometry& xray);
/** The sidecar's "geometry_from" object: the file, its frames, where the isocentre came from and
 *  the reader's warnings. */
Json xrayGeometryJson(const Options& o, const core::XrayGeometry& xray);

/** What a cone-beam .dcm output writes: each view's C-arm (a matrix-file camera's from
 *  core::cArmFromCamera about the volume's centre), and whether the views make one rotational
 *  run (one multi-frame XA; else FILE_NNNN.dcm, one XA each); or, for treatment beams (--beam,
 *  --rtplan, an RT Image's --geometry-from), each view's beam, one RT Image each. */
struct ConeDicom {
    std::vector<core::CArm> arms;
    std::vector<core::RtPlanBeam> beams; ///< RT Images instead of X-rays when not empty
    bool run = false;
};
/** The C-arms (or treatment beams) of the views (for a .dcm output or --send), before anything
 *  renders: SettingsError naming the view whose camera no C-arm (no beam's imager) has
 *  (cone_xray.cpp). */
ConeDicom coneDicom(const core::Volume& volume, const std::vector<ConeView>& views);

/** The views: the matrix file's cameras, the X-ray's (xrayViews), the treatment beams'
 *  (beamViews), else the C-arm's (one,
 *  --sweep N: primary angles 360/N apart from --primary-angle, --orbit FROM:TO:N) about the
 *  isocentre (default: the volume's centre) with the detector's pitch (default:
 *  core::framingPitch). */
std::vector<ConeView> coneViews(const Options& o, const core::Volume& volume,
                                const ConeFiles& files);

/** What the steps after loading share. */
struct ConeSession {
    const Options& options; ///< resolved for the volume (the value mapping)
    const core::Volume& volume;
    ConeCaster& caster; ///< the CPU's or the GPU's (--backend)
    double prepareMs = 0.0; ///< the caster's set-up (value mapping, empty-block map, upload)
    int threads = 0; ///< resolved (--threads, else all cores)
    const ConeFiles* files = nullptr; ///< what the camera options read
    core::DicomExportInfo exportInfo{}; ///< the input study's, for .dcm outputs
};

/** The run after loading: the views, their checks (core::validateConeView, before any
 *  rendering), --bench, then --out. Returns the exit status. */
int renderCone(const Options& o, const core::Volume& volume, const ConeFiles& files,
               const core::DicomExportInfo& exportInfo = {});

/** The projector's options from the command line (--ray-model, --step, --values, --threads). */
core::ConeProjectorOptions coneProjectorOptions(const Options& o);

/** One view's line integrals, with --flat-field folded in where it applies (see cone.cpp). */
core::DetectorImage projectConeView(const ConeSession& s, const core::ConeCamera& camera);

/** --out: renders the views and writes the images and the sidecar (outputs.cpp), all or
 *  nothing, as the parallel views are; a .dcm output as X-Ray Angiographic images carrying
 *  `dicom`'s C-arms. */
void writeConeOutputs(const ConeSession& s, const std::vector<ConeView>& views,
                      const ConeDicom& dicom = {});

/** --bench N: N views of an orbit from the first view (its C-arm's primary angle stepped
 *  360/N; a matrix file's views in turn), the ray caster's time per view as JSON (bench.cpp). */
void runConeBench(const ConeSession& s, const std::vector<ConeView>& views);
/** The views --bench times (cone.cpp). */
std::vector<ConeView> coneBenchViews(const ConeSession& s, const std::vector<ConeView>& views);

/** The "settings" object of a cone-beam run's sidecar and bench. */
Json coneSettingsJson(const ConeSession& s);
/** One view's camera: the C-arm when it placed it, source, detector, pitch, offset and P. */
Json coneViewJson(const ConeView& view);
/** The sidecar FILE.json of a cone-beam run. */
Json coneSidecarJson(const ConeSession& s, const WrittenOutput& output,
                     const std::vector<ConeView>& views);

} // namespace fvr::cli
