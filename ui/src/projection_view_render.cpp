// ProjectionView's frames: which renderer (gpu::chooseRenderer's rule), the frame at a quality
// level, its stage times, the difference to a reference view and the float projection that
// exports and measurements read.
#include <QOpenGLContext>

#include <algorithm>
#include <cmath>

#include <fvr/core/xray/display_window.h>
#include <fvr/gpu/choose_renderer.h>
#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/gpu/gpu_renderer.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

void ProjectionView::chooseRenderer() {
    m_gpu.reset();
    m_gpuCone.reset();
    m_gpuConeVolume = nullptr;
    m_polyGpu.clear();
    m_polyGpuSpectra.clear();
    m_polyOnGpu = false;
    m_cpu.reset();
    m_spectrumDirty = true;
    m_renderDirty = true;
    gpu::RendererChoice choice =
        gpu::chooseRenderer({.use = m_allowSoftwareGpu ? gpu::GpuUse::Any : gpu::GpuUse::Hardware,
                             .shareGroup = context()->shareGroup()});
    m_softwareGl = choice.gl.software();
    if (choice.onGpu()) m_gpu = std::move(choice.gpu.front());
    // A software OpenGL left to the CPU is no failure: the main window says so in its own words
    // (and how to use it anyway); a GPU that failed is said here.
    m_notice =
        choice.why == gpu::CpuReason::GpuFailed ? QString::fromStdString(choice.reason) : QString();
}

core::Renderer& ProjectionView::floatRenderer() {
    if (m_gpu) return *m_gpu;
    if (!m_cpu) m_cpu = std::make_unique<core::CpuFourierRenderer>(m_spectrum);
    return *m_cpu;
}

void ProjectionView::uploadSpectrumIfNeeded() {
    if (!m_spectrumDirty) return;
    m_spectrumDirty = false;
    m_renderDirty = true;
    m_cpu.reset(); // the old spectrum's; floatRenderer() makes the new one where it renders
    if (!m_gpu) return;
    const std::string failed = gpu::uploadSpectrum(m_gpu, m_spectrum);
    if (failed.empty()) return;
    m_notice = QString::fromStdString(failed);
    emit backendChanged(false, m_notice);
}

void ProjectionView::renderIfNeeded(bool fullQuality) {
    if (!m_spectrum || !m_volume) return;
    uploadSpectrumIfNeeded();
    m_progressive.setLevels(core::progressiveLevels(m_settings.size, m_settings.kernel,
                                                    m_spectrum->deapodizedFor.has_value(),
                                                    std::min(64, m_settings.size)));
    // Difference views compare full-quality frames (the reference renders full quality too).
    const int level = (fullQuality || m_reference) ? 0 : m_progressive.level();
    core::QualityLevel q = m_progressive.levels()[std::size_t(level)];
    if (level == 0 && !m_sliceSizeOnly) q.size = displayRenderSize(); // zoomed in: the screen's
    if (level != m_renderedLevel || q.size != m_renderedQuality.size) m_renderDirty = true;
    if (!m_renderDirty) return;
    renderFrame(renderParams(q.size, q.kernel),
                level); // same field of view at every level: d = diagonal / M
    m_renderedLevel = level;
    m_renderedQuality = q;
    if (m_reference && m_reference != this) subtractReference();
    if (!m_windowSet) windowFromFrame();
    m_renderDirty = false; // only after a frame really exists
    // Its time on screen comes when it is there (framePresented); the last frame's is not its.
    if (!m_progressive.interacting()) m_stats.wallMs = 0;
    ++m_frames;
    emit rendered();
}

void ProjectionView::recordStageTimes(const gpu::GpuStageTimes& t, bool display) {
    m_stats.sliceMs = t.sliceMs;
    m_stats.inverseMs = t.inverseMs;
    m_stats.totalMs = t.totalMs;
    m_stats.fused = t.fused;
    m_stats.displayFused = t.displayFused;
    if (display) m_stats.displayMs = t.displayMs;
}

namespace {
/** A CPU frame's stages: none fused, no display pass of its own. */
gpu::GpuStageTimes cpuStages(const core::StageTimes& t) {
    gpu::GpuStageTimes g;
    g.sliceMs = t.sliceMs;
    g.inverseMs = t.inverseMs;
    g.totalMs = t.totalMs;
    return g;
}
} // namespace

void ProjectionView::renderFrame(const core::RenderParams& params, int level) {
    m_polyOnGpu = m_polySumOnGpu = false;
    if (coneBeam()) {
        renderConeFrame(params.image.size);
        return;
    }
    // A parallel view keeps no cone-beam materials (3x the volume; context current here).
    m_polyCone.reset();
    m_polyConeGpu.clear();
    m_polyConeOnGpu = false;
    core::StageTimes t;
    if (m_poly && !m_poly->spectra.empty()) {
        if (m_gpu && renderPolychromaticOnGpu(params)) return;
        m_cpuImage = renderPolychromatic(params, &t);
        recordStageTimes(cpuStages(t), false);
        return;
    }
    m_polyGpu.clear(); // the material frames' GPU memory goes with the polychromatic output
    m_polyGpuSpectra.clear();
    if (m_gpu) {
        // With a window already set (and no difference to map), the last pass of the inverse
        // transform also writes the display texture; paintGL's displayTexture() then costs
        // nothing. Stage times are read in paintGL.
        const bool fuseDisplay = m_windowSet && !(m_reference && m_reference != this);
        m_gpu->renderToGpu(params, fuseDisplay ? &m_window : nullptr);
        m_gpuTimesPending = true;
        m_cpuImage.reset();
        return;
    }
    m_cpuImage = floatRenderer().render(params, &t);
    recordStageTimes(cpuStages(t), false);
}

void ProjectionView::subtractReference() {
    auto own = !coneBeam() && ((m_gpu && !m_poly) || m_polyOnGpu)
                   ? std::optional<core::ProjectionImage>(shownGpu().readback())
                   : m_cpuImage;
    auto ref = m_reference->projection();
    // The reference made its own context current (and released it): this view's again, or the
    // frame's texture goes to no context and the view stays empty.
    makeCurrent();
    if (!own || !ref || ref->width != own->width || ref->height != own->height) return;
    double maxAbs = 0;
    for (std::size_t i = 0; i < own->pixels.size(); ++i) {
        own->pixels[i] -= ref->pixels[i];
        maxAbs = std::max(maxAbs, double(std::abs(own->pixels[i])));
    }
    m_cpuImage = own;
    // The scale is taken anew whenever what is compared changed (a kernel, a spectrum, an
    // effect of either view), not when the views turn: the main window then windows every
    // difference view with the largest (one symmetric scale for all of them).
    const DifferenceKey key{
        m_settings,   m_reference->m_settings,   m_spectrum.get(), m_reference->m_spectrum.get(),
        m_poly.get(), m_reference->m_poly.get(), m_effects};
    if (!m_windowSet || m_diffKey != key) {
        m_diffKey = key;
        m_diffMaxAbs = maxAbs;
        m_window = {-maxAbs, maxAbs > 0 ? maxAbs : 1.0, false};
        m_windowSet = true;
        emit differenceScaleChanged();
    }
}

void ProjectionView::windowFromFrame() {
    auto img = m_cpuImage ? *m_cpuImage : shownGpu().readback();
    m_window = core::filmWindow(img.pixels, m_window.transmission, m_window.invert);
    m_windowSet = true;
    emit windowChanged(m_window, false);
}

std::optional<core::ProjectionImage> ProjectionView::projection() {
    if (!m_spectrum || !m_volume) return std::nullopt;
    const bool poly = m_poly && !m_poly->spectra.empty();
    const auto full = [this] { return renderParams(m_settings.size, m_settings.kernel); };
    if (!m_glReady) {
        if (coneBeam()) {
            renderConeFrame(m_settings.size);
            return m_cpuImage;
        }
        if (poly) return renderPolychromatic(full());
        return floatRenderer().render(full());
    }
    makeCurrent();
    std::optional<core::ProjectionImage> img;
    // Exports and measurements get the slice resolution's frame, also zoomed in (the next
    // paint renders the screen's again).
    m_sliceSizeOnly = true;
    struct Restore {
        ProjectionView* v;
        ~Restore() {
            v->m_sliceSizeOnly = false;
            if (v->displayRenderSize() != v->m_renderedQuality.size) v->update();
        }
    } restore{this};
    try {
        const int before = m_frames;
        renderIfNeeded(true); // exports and measurements always get the full-quality frame
        // A frame made here (an export, a sweep, a window preset, a difference's reference)
        // serves the changes before it: the next change is timed from itself, not from them.
        if (m_frames != before) m_frameRequested = false;
        if (coneBeam() && m_reference)
            renderConeFrame(m_settings.size), img = m_cpuImage; // its own, not the difference
        else if (coneBeam())
            img = m_cpuImage;
        else if (poly && m_reference)
            img = renderPolychromatic(full());
        else if (m_polyOnGpu || (m_gpu && !poly))
            img = shownGpu().readback(); // the view's own projection, also in difference mode
        else if (m_reference && m_cpuImage)
            img = floatRenderer().render(full());
        else
            img = m_cpuImage;
    } catch (const std::exception&) {
        img.reset();
    }
    doneCurrent();
    return img;
}

int ProjectionView::displayRenderSize() const {
    const int slice = m_settings.size;
    // A cone beam is ray cast per pixel, a polychromatic frame is one per material, a
    // difference compares slice-resolution frames: those keep the slice resolution.
    if (!m_zoomRendering || coneBeam() || m_reference || (m_poly && !m_poly->spectra.empty()))
        return slice;
    // The slice resolution is the user's detail at zoom 1; zoomed in, as much more as the
    // zoom, up to a pixel per screen pixel.
    const double onScreen = std::min(width(), height()) * m_zoom * devicePixelRatioF();
    const double need = std::min(slice * m_zoom, onScreen);
    if (need <= slice * 1.01) return slice;
    int size = slice;
    for (int s : core::settingsSizes()) {
        if (s <= slice) continue;
        size = s;
        if (s >= need) break;
    }
    return size;
}

void ProjectionView::setZoomRendering(bool on) {
    if (on == m_zoomRendering) return;
    m_zoomRendering = on;
    update();
}

core::RenderParams ProjectionView::renderParams(int M, core::Kernel kernel) const {
    // The view's settings and the shared effects as render settings: RenderParams are made in
    // one place (RenderSettings::toRenderParams), for the views as for fvr-render.
    core::RenderSettings s;
    s.kernel = kernel;
    s.voxelModel = m_settings.voxelModel;
    s.pixelAperture = m_effects.pixelAperture;
    s.depthCue = m_effects.depthCue;
    s.filter = m_effects.filter;
    s.clip = m_effects.clip;
    s.nonNegative = m_effects.nonNegative;
    return s.toRenderParams(m_view,
                            {M, core::defaultPixelSize(m_volume->dims, m_volume->spacing, M)});
}

} // namespace fvr::ui
