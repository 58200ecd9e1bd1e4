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
    // The polychromatic output once its response is there (the waiting source has none).
    const bool poly = m_poly && m_poly->response;
    const core::ValueMapping mapping = poly ? core::ValueMapping::Raw : m_spectrum->mapping;
    core::ConeProjectorOptions o;
    o.model = m_settings.cone.model;
    o.mapping = mapping;
    // The pixel aperture: 4 x 4 rays per pixel, averaged (fvr-render --pixel-aperture's rule).
    o.pixelSubsamples = m_effects.pixelAperture ? 4 : 1;
    const core::ConeCamera camera = *coneCamera(M);
    const auto t0 = std::chrono::steady_clock::now();
    if (!poly) { // the materials' volumes go with the polychromatic output
        m_polyCone.reset();
        m_polyConeGpu.clear();
        m_polyConeOnGpu = false;
    }
    std::optional<core::DetectorImage> d;
    if (poly)
        d = castPolychromaticCone(camera, o);
    else if (m_gpu)
        d = castConeOnGpu(camera, o);
    m_coneOnGpu = poly ? m_polyConeOnGpu : d.has_value();
    if (!d) {
        // The CPU caster (its mapped, padded copy of the volume) only where the CPU casts.
        if (!m_cone || m_cone->options().mapping != mapping || m_cone->options().model != o.model ||
            m_cone->options().pixelSubsamples != o.pixelSubsamples) {
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
            m_gpuCone->options().model != options.model ||
            m_gpuCone->options().pixelSubsamples != options.pixelSubsamples) {
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

core::DetectorImage ProjectionView::castPolychromaticCone(const core::ConeCamera& camera,
                                                          const core::ConeProjectorOptions& o) {
    const bool gpu = m_gpu && o.model != core::RayModel::BSpline; // no B-spline on the GPU
    if (!m_polyCone || m_polyConeVolume != m_volume.get() ||
        m_polyCone->options().model != o.model ||
        m_polyCone->options().pixelSubsamples != o.pixelSubsamples || m_polyConeOnGpu != gpu) {
        m_polyCone.reset(); // the old materials' memory first
        m_polyConeGpu.clear();
        m_polyConeOnGpu = false;
        const core::MaterialMapping mapping{core::defaultMaterials(), 70.0};
        if (gpu) {
            try {
                m_polyCone = std::make_unique<core::PolychromaticConeProjector>(
                    *m_volume, mapping, m_poly->response, o,
                    [this](const core::Volume& v, const core::ConeProjectorOptions& po) {
                        m_polyConeGpu.push_back(std::make_unique<gpu::ConeRayCaster>(v, po));
                        gpu::ConeRayCaster* c = m_polyConeGpu.back().get();
                        return [c](const core::ConeCamera& cam) { return c->project(cam); };
                    });
                m_polyConeOnGpu = true;
            } catch (const std::exception& e) { // too large for the GPU: the CPU casts
                m_polyCone.reset();
                m_polyConeGpu.clear();
                m_notice =
                    tr("Polychromatic cone beam on the CPU: %1").arg(QString::fromUtf8(e.what()));
            }
        }
        if (!m_polyCone)
            m_polyCone = std::make_unique<core::PolychromaticConeProjector>(*m_volume, mapping,
                                                                            m_poly->response, o);
        m_polyConeVolume = m_volume.get();
    } else {
        m_polyCone->setResponse(m_poly->response); // kVp, filtration, detector
    }
    core::PolychromaticConeFrame f =
        m_polyCone->project(camera, m_poly->noise, core::SpectralResponse::Output::NegativeLog);
    if (m_poly->show >= 0 && std::size_t(m_poly->show) < f.massThickness.size())
        return std::move(f.massThickness[std::size_t(m_poly->show)]);
    return std::move(f.transmission); // -ln(I/I0), the quantity shown
}

void ProjectionView::rotateCArm(double horizontalDeg, double verticalDeg) {
    if (!m_volume) return;
    const core::CArmAngles a = core::cArmAngles(*m_volume, m_view);
    double primary = std::remainder(a.primaryDeg + horizontalDeg, 360.0); // (-180, 180]
    if (primary <= -180.0) primary += 360.0;
    const double secondary = std::clamp(a.secondaryDeg - verticalDeg, -89.0, 89.0);
    setViewFrame(core::cArmViewFrame(*m_volume, primary, secondary));
    emit viewFrameChanged(m_view);
}

} // namespace fvr::ui
