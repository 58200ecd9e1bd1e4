#pragma once
/** The 2D/3D registration's DRRs on the GPU (core/registration/registration.h): every view of a
 *  pose in one dispatch of ConeRayCaster::projectMany, read back for the similarity on the CPU.
 *  The renderers need the current OpenGL 4.3 context of the registering thread (an EglContext
 *  made on it, or the caller's own). */
#include <fvr/core/registration/registration.h>
#include <fvr/gpu/cone_ray_caster.h>

namespace fvr::gpu {

/** Makes a ConeRayCaster per level (the level's CT uploaded once). The caster refuses the
 *  B-spline model (SettingsError) and volumes the GPU cannot hold (GpuMemoryError). */
core::DrrRendererFactory gpuDrrRendererFactory(TrilinearFetch fetch = TrilinearFetch::Manual);

} // namespace fvr::gpu
