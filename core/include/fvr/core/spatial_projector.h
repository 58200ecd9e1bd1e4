#pragma once
/** The spatial-domain reference: the same projection by ray integration through the volume with
 *  trilinear sampling (zero outside) and a fine step. O(M^2 N) per view: for tests, for the
 *  accuracy readout, and as the ray-casting baseline in benchmarks. */
#include <fvr/core/projection.h>
#include <fvr/core/spectrum.h>
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
};

class SpatialProjector {
public:
    SpatialProjector(const Volume& volume, SpatialProjectorOptions options = {});
    /** Pixel (col,row) = integral along D through c + (col-M/2) d R - (row-M/2) d U, c the
     *  volume's physical centre, of the trilinearly interpolated (mapped) volume, weighted by the
     *  depth cueing weight when options.depthCue > 0. */
    ProjectionImage project(const ViewFrame& view, const ImageGeometry& image);

private:
    const Volume& m_volume;
    SpatialProjectorOptions m_options;
    std::vector<float> m_mapped; // values after the mapping (mu); empty for Raw
    ThreadPool m_pool;
};

} // namespace fvr::core
