// ProjectionView's cone beam: the C-arm of the view frame ray cast on the CPU, and the drag that
// moves the C-arm.
#include <algorithm>
#include <chrono>
#include <cmath>

#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

std::optional<core::ConeCamera> ProjectionView::coneCamera(int size) const {
    if (!coneBeam() || !m_volume) return std::nullopt;
    return core::cArmCameraForView(*m_volume, m_view, m_settings.cone.sid, m_settings.cone.sod,
                                   size > 0 ? size : m_settings.size);
}

void ProjectionView::renderConeFrame(int M) {
    const core::ValueMapping mapping = m_spectrum->mapping;
    core::ConeProjectorOptions o;
    o.model = m_settings.cone.model;
    o.mapping = mapping;
    const core::ConeCamera camera = *coneCamera(M);
    const auto t0 = std::chrono::steady_clock::now();
    std::optional<core::DetectorImage> d = m_gpu ? castConeOnGpu(camera, o) : std::nullopt;
    m_coneOnGpu = d.has_value();
    if (!d) {
        // The CPU caster (its mapped, padded copy of the volume) only where the CPU casts.
        if (!m_cone || m_cone->options().mapping != mapping || m_cone->options().model != o.model) {
            m_cone.reset(); // the old one's memory first
            m_cone = std::make_unique<core::ConeProjector>(*m_volume, o);
        }
        d = m_cone->project(camera);
    } else {
        m_cone.reset();
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    core::ProjectionImage img;
    img.width = img.height = M;
    img.pixelSize = camera.pitchU * m_settings.cone.sod / m_settings.cone.sid;
    img.view = m_view;
    img.mapping = mapping;
    img.pixels = std::move(d->pixels);
    m_cpuImage = std::move(img);
    m_stats.sliceMs = 0.0;
    m_stats.inverseMs = 0.0;
    m_stats.totalMs = ms;
    m_stats.fused = m_stats.displayFused = false;
}

std::optional<core::DetectorImage> ProjectionView::castConeOnGpu(
    const core::ConeCamera& camera, const core::ConeProjectorOptions& options) {
    if (options.model == core::RayModel::BSpline) return std::nullopt; // CPU only
    try {
        if (!m_gpuCone || m_gpuConeVolume != m_volume.get() ||
            m_gpuCone->options().mapping != options.mapping ||
            m_gpuCone->options().model != options.model) {
            m_gpuCone.reset(); // the old one's GPU memory first
            m_gpuCone = std::make_unique<gpu::ConeRayCaster>(*m_volume, options);
            m_gpuConeVolume = m_volume.get();
        }
        return m_gpuCone->project(camera);
    } catch (const std::exception& e) {
        // Too large for a 3D texture, out of GPU memory, a shader the driver refuses: the CPU.
        m_gpuCone.reset();
        m_gpuConeVolume = nullptr;
        m_notice = tr("Cone beam on the CPU: %1").arg(QString::fromUtf8(e.what()));
        return std::nullopt;
    }
}

void ProjectionView::dragCArm(const QPoint& delta) {
    if (!m_volume) return;
    const double k = 180.0 / std::max(1, std::min(width(), height())); // degrees per pixel
    const core::CArmAngles a = core::cArmAngles(*m_volume, m_view);
    double primary = a.primaryDeg + delta.x() * k;
    if (primary > 180.0) primary -= 360.0;
    if (primary <= -180.0) primary += 360.0;
    const double secondary = std::clamp(a.secondaryDeg - delta.y() * k, -89.0, 89.0);
    setViewFrame(core::cArmViewFrame(*m_volume, primary, secondary));
    emit viewFrameChanged(m_view);
}

} // namespace fvr::ui
