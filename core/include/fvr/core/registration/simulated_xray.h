#pragma once
/** Simulated X-rays for testing and benchmarking 2D/3D registration: an image formation unlike
 *  the registration's own DRRs (monoenergetic mu line integrals, trilinear), so that a match is
 *  never exact by construction:
 *   - the CT numbers shifted by `huOffset` (a scanner's calibration offset);
 *   - a polychromatic tube spectrum (TASMIP at `kvp`, 2.5 mm Al), materials by Schneider's
 *     decomposition (polychromatic_cone.h), so bone and soft tissue harden the beam;
 *   - the box voxel model (exact path lengths), not trilinear;
 *   - quantum noise at `mAs` (0: none) on the detector's pixels;
 *   - a Gaussian detector blur of `blurPixels` standard deviation;
 *   - the result as -ln(I / I0), a flat-fielded radiograph's line integrals. */
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/volume.h>

namespace fvr::core {

struct XraySimulation {
    double kvp = 100.0;
    double mAs = 1.0;
    double blurPixels = 0.8;
    double huOffset = 25.0;
    std::uint64_t seed = 1;
    int threads = 0;
};

/** -ln(I / I0) (W x H of the camera, row 0 at the top) of the CT (Hounsfield units, else
 *  SettingsError) at pose T (registration/pose.h) seen by `camera`. */
std::vector<float> simulateXray(const Volume& ct, const ConeCamera& camera, const glm::dmat4& T,
                                const XraySimulation& simulation = {});

/** A Gaussian blur of standard deviation `sigma` pixels (separable, the edges clamped), in
 *  place; sigma <= 0 leaves the image as it is. */
void gaussianBlur(std::vector<float>& image, int width, int height, double sigma);

} // namespace fvr::core
