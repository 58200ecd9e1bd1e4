#pragma once
/** The projection on screen: a QOpenGLWidget driving fvr::gpu::GpuFourierRenderer (the CPU
 *  renderer when no usable GPU exists, with a visible notice), with trackball rotation, zoom,
 *  pan, window/level, patient orientation labels and an fps overlay. */
#include <QElapsedTimer>
#include <QOpenGLWidget>

#include <memory>
#include <optional>

#include <fvr/core/io/image_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/progressive.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/polychromatic_cone.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/ui/measure_geometry.h>
#include <fvr/ui/view_overlay.h>
#include <fvr/ui/view_settings.h>

class QOpenGLShaderProgram;
class QOpenGLTexture;
class QOpenGLVertexArrayObject;

namespace fvr::gpu {
class ConeRayCaster;
class GpuFourierRenderer;
struct GpuStageTimes;
} // namespace fvr::gpu

namespace fvr::ui {

class MeasureLayer;

class ProjectionView : public QOpenGLWidget {
    Q_OBJECT
public:
    explicit ProjectionView(QWidget* parent = nullptr);
    ~ProjectionView() override;

    void setStudy(std::shared_ptr<const core::Volume> volume,
                  std::shared_ptr<const core::Spectrum> spectrum);
    /** Instead of an image while the view has no spectrum: why (e.g. its kernel's spectrum is
     *  being prepared); empty: "No study loaded". */
    void setPendingText(const QString& text, bool failed = false);
    const QString& pendingText() const { return m_pending; }
    /** The spectrum it waits for will not come (cancelled, out of memory, an error). */
    bool pendingFailed() const { return m_pendingFailed; }
    /** The last render failure ("Not rendered: …"), empty after a good frame. */
    const QString& renderError() const { return m_renderError; }
    const std::shared_ptr<const core::Volume>& volume() const { return m_volume; }
    const std::shared_ptr<const core::Spectrum>& spectrum() const { return m_spectrum; }
    void setSettings(const ViewSettings& s);
    const ViewSettings& settings() const { return m_settings; }
    void setEffects(const FrameEffects& e);
    /** The polychromatic output (null: the spectrum's line integrals, as before): the view
     *  renders one frame per material on the CPU and shows -ln(I/I0) or one material. A new
     *  response or noise re-renders without new renderers; new spectra make them anew. A
     *  source without spectra: they are being prepared (the view shows its line integrals
     *  meanwhile and is not showsCurrentFrame()). */
    void setPolychromatic(std::shared_ptr<const PolychromaticSource> source);
    const std::shared_ptr<const PolychromaticSource>& polychromatic() const { return m_poly; }
    /** A cone-beam view (settings().projection): the C-arm camera of its current frame and
     *  size (core::cArmCameraForView); nothing for a parallel view or without a study. */
    std::optional<core::ConeCamera> coneCamera(int size = 0) const;
    /** The last frame's spectral sum ran on the GPU (the view renders there). */
    bool polychromaticOnGpu() const { return m_polySumOnGpu; }
    const FrameEffects& effects() const { return m_effects; }
    /** Progressive refinement: the frame rate to hold while dragging (0: off). */
    void setTargetFps(double fps);
    /** Marks a drag (also set by the main window on synchronised views): frames render at the
     *  controller's interactive level; leaving it renders the full-quality frame. */
    void setInteracting(bool on);
    const core::ProgressiveController& progressive() const { return m_progressive; }
    /** The quality level of the frame on screen (0: full quality). */
    int displayedLevel() const { return m_displayedLevel; }
    /** Size of the frame on screen (differs from settings().size at interactive levels). */
    int displayedSize() const { return m_displayedSize; }
    /** Tests: a slow machine. Every frame rendered also waits `msAt512` × (M / 512)² ms (a
     *  renderer whose cost grows with the pixel count), in real time: the wall clock sees it,
     *  the renderer's stage timers do not. */
    void setSimulatedRenderCost(double msAt512) { m_simulatedMsAt512 = msAt512; }
    void setViewFrame(const core::ViewFrame& f);
    const core::ViewFrame& viewFrame() const { return m_view; }
    void setWindow(const core::DisplayWindow& w);
    const core::DisplayWindow& window() const { return m_window; }
    /** Window from the current projection's percentiles (0.5..99.5). */
    void autoWindow();
    /** Zoom: the image's side is the view's shorter side times `zoom` (0.1 to 40). Zoomed in,
     *  the full-quality frame renders at the screen's resolution (displayRenderSize()), not
     *  the slice resolution's pixels magnified. */
    void setZoom(double zoom);
    double zoom() const { return m_zoom; }
    /** Zoomed-in frames at the screen's resolution (on by default; the main window turns it off
     *  in Difference mode, whose views compare frames of the slice resolution). */
    void setZoomRendering(bool on);
    /** The size the full-quality frame on screen renders at: the slice resolution, or zoomed in
     *  (a parallel view, line integrals or Beer-Lambert) the smallest size of the Rendering
     *  panel's (a power of two up to 2048) with the zoom times the slice resolution's pixels,
     *  or a pixel per screen pixel where that is less. The same field of
     *  view at every size: the Fourier slice samples the spectrum more finely, so the frame is
     *  the band-limited projection at that resolution, never an interpolated magnification.
     *  Exports, measurements and differences keep the slice resolution (projection()). */
    int displayRenderSize() const;
    /** The image's offset from the view's centre, in widget pixels (a middle drag). */
    QPointF pan() const { return m_pan; }
    void setPan(const QPointF& pan);
    /** Turns the view as a drag of `horizontalDeg` to the right and `verticalDeg` down would
     *  (the object follows): about the screen's vertical and horizontal axes for a parallel
     *  view, the C-arm's primary and secondary angles for a cone beam. Emits viewFrameChanged. */
    void rotateBy(double horizontalDeg, double verticalDeg);
    void resetPanZoom();
    void setOverlayVisible(bool on);
    bool overlayVisible() const { return m_overlay; }
    /** When set, this view shows (own projection - reference) with a symmetric window. */
    void setDifferenceReference(ProjectionView* reference);
    ProjectionView* differenceReference() const { return m_reference; }
    /** Difference mode: the largest |difference| of the frame the view's scale was last taken
     *  from (taken anew when its kernel, size, voxel model, spectrum or effects, or the
     *  reference's, change; not when the view turns); 0 before any difference frame. The main
     *  window windows all difference views with the largest of them (one shared scale). */
    double differenceMaxAbs() const { return m_diffMaxAbs; }
    /** The units of the values the view shows ("mm", "HU·mm", "−ln(I/I0)", "g/cm²"). */
    QString valueUnits() const;
    /** The spectrum the view renders from, in words: values, transform, oversampling, and
     *  whether it is gridding corrected for the view's kernel (compare views differ). */
    QString spectrumText() const;
    /** Why progressive refinement is off although a target frame rate is set (the overlay
     *  says so instead of dropping the line); empty: not off for a reason. */
    void setProgressiveOffReason(const QString& reason);
    /** Title drawn in the top-left corner (compare mode). */
    void setTitle(const QString& title);

    /** What a frame of size M with this kernel renders: the view, the same field of view at every
     *  M (the volume's diagonal), and the effects. Needs a study. */
    core::RenderParams renderParams(int M, core::Kernel kernel) const;
    /** The float projection of the current view and settings (renders if needed). */
    std::optional<core::ProjectionImage> projection();
    /** What the view shows, as an image of the widget's framebuffer. */
    QImage screenshot();
    /** The patient-direction labels at the image's left, right, top and bottom edges ("L",
     *  "S", ...; with " (assumed)" when the file states no orientation). */
    QStringList orientationLabels() const;
    /** Where the labels are drawn (left, right, top, bottom): at the image's edges, and below
     *  the overlay box where they would fall under it. */
    QList<QRect> orientationLabelRects() const;
    /** The overlay box (title, performance lines) in widget coordinates; null without one. */
    QRect overlayBox() const;
    /** The overlay box's lines: the title, the performance overlay, the difference note. */
    QString overlayText() const;
    /** Difference mode: the colour bar's labels, top to bottom, with units; empty without one. */
    QStringList colourBarLabels() const;
    /** Where the colour bar is drawn (widget coordinates); null without one. */
    QRect colourBarRect() const;
    bool usingGpu() const { return m_gpu != nullptr; }
    /** Whether the view may render on a software GPU (llvmpipe …); by default it renders on
     *  the CPU there, which is faster. A hardware GPU is always used. */
    void setAllowSoftwareGpu(bool allow);
    /** The OpenGL of this view is a software renderer (known once the view is shown). */
    bool softwareGl() const { return m_softwareGl; }
    QString backendNotice() const { return m_notice; }
    /** Stage times of the last frame and the wall-clock time the user saw (FrameStats). */
    FrameStats frameStats() const { return m_stats; }
    /** The frame on screen is the full-quality frame of the current study, spectrum, view and
     *  settings (nothing left to render, no drag). */
    bool showsCurrentFrame() const {
        return m_spectrum && !m_spectrumDirty && !m_renderDirty && m_frames > 0 &&
               !(m_poly && m_poly->spectra.empty()) && // material spectra still coming
               m_displayedLevel == 0 && m_renderedLevel == 0 && !m_progressive.interacting() &&
               m_displayedSize == displayRenderSize(); // zoomed in: the screen's resolution
    }
    /** Number of frames rendered (tests). */
    int framesRendered() const { return m_frames; }
    /** The reader's tools on this view: measurements, annotations, the value under the cursor
     *  and the scale bar (measure_layer.h). */
    MeasureLayer& measure() const { return *m_measure; }
    /** Where the image is drawn, in widget coordinates (zoom and pan included). */
    QRectF imageRectInWidget() const { return imageRect(); }
    /** Turns or mirrors the displayed image by turning the view (projection_view_measure.cpp):
     *  a quarter turn about the view direction, or the view from the opposite side (of a
     *  parallel projection, exactly the mirror image). The orientation labels follow, and the
     *  annotations move with the image. */
    void turnImage(measure::Turn t);

signals:
    void viewFrameChanged(const core::ViewFrame& f);
    /** The view's window changed: `byHand` for a drag, false for an automatic window. */
    void windowChanged(const core::DisplayWindow& w, bool byHand);
    void rendered();
    void backendChanged(bool gpu, const QString& notice);
    /** A drag on this view started or ended (the main window mirrors it on the other views). */
    void interactionChanged(bool on);
    /** Difference mode: differenceMaxAbs() was taken anew (the shared scale may change). */
    void differenceScaleChanged();
    /** Zoom or pan changed (the wheel, a middle drag, the keys or a reset). */
    void panZoomChanged();

protected:
    void initializeGL() override;
    void paintGL() override;
    void resizeGL(int w, int h) override;
    void mousePressEvent(QMouseEvent* e) override;
    void mouseMoveEvent(QMouseEvent* e) override;
    void mouseReleaseEvent(QMouseEvent* e) override;
    void wheelEvent(QWheelEvent* e) override;
    void focusOutEvent(QFocusEvent* e) override;

private:
    void releaseGl();
    /** With the context current: the renderer by gpu::chooseRenderer's rule (a software GL only
     *  when allowed); the notice says why the CPU where the GPU failed. */
    void chooseRenderer();
    void renderIfNeeded(bool fullQuality = false);
    /** The renderer of float images: the GPU's when there is one, else the CPU's (made on demand).
     */
    core::Renderer& floatRenderer();
    /** A new spectrum goes to the GPU (the CPU renderer, made by floatRenderer(), when that
     *  fails or there is no GPU). */
    void uploadSpectrumIfNeeded();
    /** One frame at a quality level: on the GPU into its buffers (and display texture), or the
     *  CPU's float image with its stage times. */
    void renderFrame(const core::RenderParams& params, int level);
    /** The polychromatic frame of m_poly: -ln(I/I0) or the material it shows. */
    core::ProjectionImage renderPolychromatic(const core::RenderParams& params,
                                              core::StageTimes* times = nullptr);
    /** A cone-beam frame of M x M on the CPU (the C-arm of the view frame), as a projection
     *  image whose pixel size is the detector's pitch at the isocentre. */
    void renderConeFrame(int M);
    /** The frame on the GPU (context current, the view renders there); nothing where it cannot
     *  (the B-spline model, a volume too large: the CPU casts it, the notice says why). */
    std::optional<core::DetectorImage> castConeOnGpu(const core::ConeCamera& camera,
                                                     const core::ConeProjectorOptions& options);
    /** The polychromatic cone beam of m_poly's response (one ray caster per material's density
     *  volume, made once per volume, model, rays per pixel and backend: the GPU's where the
     *  view renders there, context current, else the CPU's): -ln(I/I0) with m_poly's noise, or
     *  the mass thickness (g/cm^2) of the material it shows. */
    core::DetectorImage castPolychromaticCone(const core::ConeCamera& camera,
                                              const core::ConeProjectorOptions& options);
    bool coneBeam() const { return m_settings.projection == ProjectionKind::Cone; }
    /** rotateBy() on a cone-beam view: horizontal moves the primary angle (to the right:
     *  toward LAO), vertical the secondary (up: toward cranial, clamped to ±89°). */
    void rotateCArm(double horizontalDeg, double verticalDeg);
    /** The same on the GPU (the view renders there): one GPU renderer per material, the
     *  spectral sum in one compute pass into the first one's frame, shown without a read-back
     *  (with noise: I/I0 read back once, the noise drawn on the CPU). False where it cannot
     *  (the caller renders on the CPU). */
    bool renderPolychromaticOnGpu(const core::RenderParams& params);
    /** The GPU renderer whose frame the view shows (the polychromatic sum's, or m_gpu). */
    gpu::GpuFourierRenderer& shownGpu() { return m_polyOnGpu ? *m_polyGpu.front() : *m_gpu; }
    /** The stage times of the frame just rendered; the display time only with `display` (the
     *  GPU's own frame: other frames keep the last one). The wall-clock time comes when the
     *  frame is on screen (framePresented). */
    void recordStageTimes(const gpu::GpuStageTimes& t, bool display);
    /** Difference mode: the frame minus the reference view's projection. */
    void subtractReference();
    /** The first frame of a study sets the window from its image. */
    void windowFromFrame();
    /** A change that needs a new frame: the wall clock runs from the first one until that
     *  frame is on screen. */
    void requestFrame();
    /** The window's frame is on screen (QOpenGLWidget::frameSwapped): the wall-clock time of
     *  the frame this view rendered for it goes to the progressive controller. */
    void framePresented();
    void endDrag();
    /** The texture showing the frame through the window (0: none): the GPU's display texture,
     *  or the CPU image uploaded. */
    unsigned frameTexture();
    void uploadCpuTexture(const core::ProjectionImage& image);
    /** What the overlay shows now (ViewOverlay lays it out and paints it). */
    OverlayState overlayState() const;
    ViewOverlay overlay() const { return ViewOverlay(overlayState()); }
    void drawOverlay();
    QRectF imageRect() const;

    std::shared_ptr<const core::Volume> m_volume;
    std::shared_ptr<const core::Spectrum> m_spectrum;
    bool m_spectrumDirty = false;
    bool m_renderDirty = true;
    ViewSettings m_settings;
    FrameEffects m_effects;
    core::ProgressiveController m_progressive;
    int m_renderedLevel = 0, m_displayedLevel = 0, m_displayedSize = 0;
    core::QualityLevel m_renderedQuality; ///< what the last frame rendered with
    double m_simulatedMsAt512 = 0.0;
    core::ViewFrame m_view;
    core::DisplayWindow m_window{0.0, 1.0, false};
    bool m_windowSet = false;
    double m_zoom = 1.0;
    QPointF m_pan{0, 0};
    bool m_overlay = true;
    QString m_title;
    QString m_pending;
    bool m_pendingFailed = false;
    ProjectionView* m_reference = nullptr;
    /** What a difference view's scale was taken for (DifferenceKey: both views' settings,
     *  spectra, effects and polychromatic sources). */
    struct DifferenceKey {
        ViewSettings own, ref;
        const void *ownSpectrum = nullptr, *refSpectrum = nullptr, *ownPoly = nullptr,
                   *refPoly = nullptr;
        FrameEffects effects;
        bool operator==(const DifferenceKey&) const = default;
    };
    std::optional<DifferenceKey> m_diffKey;
    double m_diffMaxAbs = 0.0;
    QString m_progressiveOff;
    bool m_zoomRendering = true;
    bool m_sliceSizeOnly = false; ///< projection(): the frame at the slice resolution

    std::unique_ptr<gpu::GpuFourierRenderer> m_gpu;
    std::unique_ptr<core::CpuFourierRenderer> m_cpu;
    std::unique_ptr<core::ConeProjector> m_cone; ///< made for the volume, mapping and ray model
    /** The cone beam on the GPU where the view renders there (its GL objects: released with
     *  the context current), for the volume m_gpuConeVolume. */
    std::unique_ptr<gpu::ConeRayCaster> m_gpuCone;
    const core::Volume* m_gpuConeVolume = nullptr;
    bool m_coneOnGpu = false; ///< the last cone-beam frame was cast on the GPU
    /** The polychromatic cone beam's casters (the materials' volumes: 3x the CT's memory), for
     *  the volume m_polyConeVolume; released when the output is line integrals again. */
    std::unique_ptr<core::PolychromaticConeProjector> m_polyCone;
    const core::Volume* m_polyConeVolume = nullptr;
    /** m_polyCone's GPU casters, one per material (released with the context current). */
    std::vector<std::unique_ptr<gpu::ConeRayCaster>> m_polyConeGpu;
    bool m_polyConeOnGpu = false; ///< m_polyCone casts on the GPU
    std::optional<core::ProjectionImage> m_cpuImage; // CPU path / difference mode
    std::shared_ptr<const PolychromaticSource> m_poly;
    std::unique_ptr<core::PolychromaticRenderer> m_polyRenderer;
    std::vector<std::unique_ptr<gpu::GpuFourierRenderer>> m_polyGpu; ///< one per material
    std::vector<std::shared_ptr<const core::Spectrum>> m_polyGpuSpectra;
    bool m_polyOnGpu = false; ///< the shown frame is the GPU's spectral sum (no read-back)
    bool m_polySumOnGpu = false; ///< the last frame's spectral sum ran on the GPU
    QString m_notice; ///< backend notice (CPU fallback)
    bool m_allowSoftwareGpu = false;
    bool m_softwareGl = false;
    QString m_renderError; ///< last render failure, cleared by the next good frame
    std::unique_ptr<QOpenGLShaderProgram> m_quad;
    std::unique_ptr<QOpenGLVertexArrayObject> m_vao;
    unsigned m_cpuTexture = 0;
    int m_cpuTextureSize = 0;
    bool m_glReady = false;
    bool m_gpuTimesPending = false;

    Qt::MouseButton m_dragButton = Qt::NoButton;
    Qt::KeyboardModifiers m_dragMods;
    QPoint m_lastPos;
    FrameStats m_stats;
    QElapsedTimer m_requestClock; ///< since the first change not yet on screen
    bool m_frameRequested = false;
    bool m_framePending = false; ///< a new frame was painted and is not on screen yet
    int m_pendingLevel = 0;
    int m_frames = 0;
    MeasureLayer* m_measure = nullptr; ///< a child QObject
};

} // namespace fvr::ui
