#pragma once
/** Cone-beam DRRs by ray casting: each detector pixel holds the line integral of the volume's
 *  voxel model from the camera's source to that pixel's centre (geometry/camera.h), in the units
 *  of the parallel renderers' line integrals (value x mm; mm of water for mu). The volume stands
 *  in patient LPS by its origin, spacing and direction cosines (volume.h). Three voxel models:
 *   - Box: each voxel a constant cube (exact path lengths, Siddon's model; what
 *     `plastimatch drr -i exact` computes);
 *   - Trilinear: the default, as the parallel renderers' default model; integrated exactly by
 *     default (within a cell between 8 voxel centres the interpolant is a cubic polynomial
 *     along any ray, so Simpson's rule per cell is exact), or sampled with a chosen step;
 *   - BSpline: the cubic B-spline through the voxels (zeros outside), sampled with a step.
 *  The rays run on a thread pool, clipped to the model's support and to [source, pixel]; runs of
 *  8^3 blocks whose values are all 0 (air after the mu mapping, masked volumes) are skipped. */
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/volume.h>

namespace fvr::core {

enum class RayModel { Trilinear, BSpline, Box };

/** "trilinear", "bspline", "box". */
const char* rayModelName(RayModel m);
/** Inverse of rayModelName (also "linear", "cubic", "b-spline", "exact", "siddon");
 *  throws SettingsError naming the accepted names. */
RayModel parseRayModel(const std::string& name);

struct ConeProjectorOptions {
    RayModel model = RayModel::Trilinear;
    /** The step along a ray as a fraction of the smallest voxel spacing. Trilinear: 0 integrates
     *  exactly (per cell), > 0 takes midpoint samples at that step. BSpline: 0 means 0.25. Box:
     *  not used (exact path lengths). At most 4. */
    double stepFraction = 0.0;
    ValueMapping mapping = ValueMapping::Raw;
    int threads = 0; ///< <= 0: every hardware thread
    /** n x n rays per pixel, averaged (the pixel's area instead of its centre), 1..16. */
    int pixelSubsamples = 1;
    /** Skip 8^3 blocks of zeros (exact: such blocks add nothing to any model's integral). */
    bool skipEmpty = true;
};

/** A W x H detector image: pixel (col, row) at row * width + col, row 0 at the top. */
struct DetectorImage {
    int width = 0;
    int height = 0;
    ConeCamera camera;
    ValueMapping mapping = ValueMapping::Raw;
    std::vector<float> pixels;

    float at(int col, int row) const { return pixels[std::size_t(row) * width + col]; }
};

/** Voxel index (i, j, k) lies at origin + sum_a direction[a] spacing[a] index[a] (LPS mm). */
glm::dmat4 indexToPatient(const Volume& volume);
/** The physical centre of the voxel grid, ((N-1)/2 per axis), in LPS: the default isocentre. */
glm::dvec3 volumeCentre(const Volume& volume);

/** The detector pitch (mm, square pixels) that fits the volume's diagonal, magnified at the
 *  isocentre by SID/SOD, on the smaller of W and H. */
double framingPitch(const Volume& volume, double sid, double sod, int width, int height);

/** camera.validate(), then the camera against the volume: SettingsError when the source lies
 *  inside the volume's box, when the whole volume lies behind the source, or when it lies
 *  beyond the detector. */
void validateConeView(const ConeCamera& camera, const Volume& volume);

/** A real flat-panel's response to an open beam, relative to the pixel under the source's foot
 *  on the detector plane: inverse square times obliquity, (SID / r)^3 with r the distance from
 *  the source to the pixel's centre. Multiplies transmitted intensities (I = I0 f exp(-p)),
 *  never line integrals. Off by default in every front end. */
std::vector<float> detectorFlatField(const ConeCamera& camera);

/** The parallel renderers' view frame (in the volume's index frame) that a C-arm at these
 *  angles shows: the same columns (u) and rows (v) on the screen, D from the detector toward the
 *  source (so that R = D x U, as patientViewFrame's AP is at 0/0 for an LPS volume). Comparing
 *  a parallel frame with the cone beam of the same angles shows only what the cone adds. */
ViewFrame cArmViewFrame(const Volume& volume, double primaryDeg, double secondaryDeg);

/** The C-arm angles (degrees) of a view frame, as cArmViewFrame makes them: primary in
 *  (-180, 180], secondary in [-90, 90]; a frame's roll about its direction is not a C-arm
 *  angle and is dropped (at +-90 secondary the primary comes from the frame's columns). */
struct CArmAngles {
    double primaryDeg = 0.0;
    double secondaryDeg = 0.0;
};
CArmAngles cArmAngles(const Volume& volume, const ViewFrame& frame);

/** "LAO 30° CRAN 15°" (RAO for negative primary, CAUD for negative secondary; 0 as "LAO 0°"),
 *  whole degrees, as a cath lab reads them. */
std::string cArmLabel(double primaryDeg, double secondaryDeg);

/** The camera the workstation renders for a parallel frame: the C-arm of its angles about the
 *  volume's centre, a square M x M detector whose pitch frames the volume (framingPitch). */
ConeCamera cArmCameraForView(const Volume& volume, const ViewFrame& frame, double sid, double sod,
                             int size);

class ConeProjector {
public:
    /** Maps the values (options.mapping) and prepares the model's data (B-spline coefficients,
     *  the empty-block map) once; SettingsError for bad options. The volume must outlive it. */
    explicit ConeProjector(const Volume& volume, ConeProjectorOptions options = {});
    ~ConeProjector();
    ConeProjector(const ConeProjector&) = delete;
    ConeProjector& operator=(const ConeProjector&) = delete;

    const ConeProjectorOptions& options() const { return m_options; }
    /** The line integrals of one view (validateConeView first). */
    DetectorImage project(const ConeCamera& camera);

    struct Data;

private:
    const Volume& m_volume;
    ConeProjectorOptions m_options;
    std::unique_ptr<Data> m_data;
    ThreadPool m_pool;
};

/** Words for the sidecar and the bench: "trilinear ray casting, exact per cell" etc. */
std::string describeConeProjector(const ConeProjectorOptions& options);

} // namespace fvr::core
