#pragma once
/** The spatial-domain reference: the same projection by ray integration through the volume's
 *  voxel model (trilinear, or the cubic B-spline through the voxels; zero outside, with the
 *  model's ramp across the boundary) and a fine step. O(M^2 N) per view: for tests, for the
 *  accuracy readout, and as the ray-casting baseline in benchmarks. */
#include <string>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/volume.h>

namespace fvr::core {

struct SpatialProjectorOptions {
    /** Step along the ray as a fraction of the smallest voxel spacing. */
    double stepFraction = 0.25;
    ValueMapping mapping = ValueMapping::Raw;
    int threads = 0;
    /** Depth cueing strength (xray.h): each sample weighted by w(t) = a + b t, t its depth. */
    double depthCue = 0.0;
    /** Trilinear (as DRR ray casters) or BSpline: the cubic B-spline interpolant of the voxels
     *  padded with zeros (coefficients from the exact recursive prefilter over a margin where
     *  they decay below 1e-6). BandLimited has no ray caster here: SettingsError. */
    VoxelModel voxelModel = VoxelModel::Trilinear;
    /** n x n rays per pixel, averaged: the pixel's area instead of its centre (a detector pixel
     *  integrates over its area). 1: point sampling at the pixel centre. */
    int pixelSubsamples = 1;
};

/** The cubic B-spline coefficients of a volume padded with `margin` zero voxels per side:
 *  sum_n c[n] beta3(x - n) = v[x] at every integer x, v = 0 outside the volume (recursive
 *  prefilter, pole sqrt(3) - 2, with the exact infinite-domain boundary values). Layout: x fastest,
 *  dims + 2 margin per axis, voxel (0,0,0) at (margin, margin, margin). */
std::vector<float> bsplineCoefficients(const std::vector<float>& voxels, const Dims3& dims,
                                       int margin);

/** The ray caster for what a frame rendered with `params` approximates (the accuracy readout,
 *  fvr-render --bench): the same voxel model (trilinear for the band-limited model, which has no
 *  ray caster here), the same depth cueing, and with the pixel aperture the pixel's area (3 x 3
 *  rays per pixel). Step s/4. */
SpatialProjectorOptions matchingProjectorOptions(const RenderParams& params, ValueMapping mapping,
                                                 int threads = 0);
/** The reference in words, e.g. "trilinear ray casting (step s/4, 3 x 3 rays per pixel)"; for a
 *  band-limited frame it adds that the difference includes the voxel model. */
std::string describeProjector(const SpatialProjectorOptions& options, VoxelModel rendered);

class SpatialProjector {
public:
    SpatialProjector(const Volume& volume, SpatialProjectorOptions options = {});
    /** Pixel (col,row) = integral along D through c + (col-M/2) d R - (row-M/2) d U, c the
     *  volume's physical centre, of the interpolated (mapped) volume, weighted by the depth
     *  cueing weight when options.depthCue > 0 (averaged over the pixel with pixelSubsamples). */
    ProjectionImage project(const ViewFrame& view, const ImageGeometry& image);

private:
    const Volume& m_volume;
    SpatialProjectorOptions m_options;
    std::vector<float> m_mapped; // values after the mapping (mu); empty for Raw
    std::vector<float> m_coefficients; // BSpline: prefiltered, with kSplineMargin voxels per side
    ThreadPool m_pool;
};

} // namespace fvr::core
