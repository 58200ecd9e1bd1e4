#pragma once
/** What a projection view draws over its image: the title and performance box in the top-left
 *  corner, the patient-direction labels at the image's edges (clear of that box), the notice at
 *  the bottom, or the "no study" text instead of an image. Laid out from a plain state, with no
 *  GL and no widget: ProjectionView fills the state in and paints through it, and the tests
 *  check the lines and boxes of a state they make up. */
#include <QCoreApplication>
#include <QFont>
#include <QList>
#include <QRect>
#include <QSize>
#include <QString>
#include <QStringList>

#include <optional>

#include <fvr/core/render/progressive.h>
#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/display_window.h>
#include <fvr/ui/view_settings.h>

class QPainter;

namespace fvr::ui {

/** Stage times of the last frame (ms): slice, inverse, display, total; and what the user saw:
 *  the wall-clock time from the change (a drag step) to the frame on screen. */
struct FrameStats {
    double sliceMs = 0, inverseMs = 0, displayMs = 0, totalMs = 0;
    double wallMs = 0; ///< change to frame on screen (what progressive refinement holds)
    bool fused = false;
    bool displayFused = false;
};

/** Everything the overlay shows, as the view has it. */
struct OverlayState {
    QSize widget; ///< the view's size
    QRectF image; ///< where the image lies in the view (zoom and pan applied)
    QFont font; ///< the view's font (the overlay's is that, at least 8 pt)
    bool hasImage = false; ///< a spectrum to render; false: the pending text instead of an image
    QString pending; ///< why there is no image yet; empty: "No study loaded"
    QString title; ///< compare mode: the view's title (top-left)
    bool performance = true; ///< the performance lines (the overlay switch)
    std::optional<QString> differenceTo; ///< difference mode: the reference view's title
    QStringList labels; ///< patient directions at left, right, top, bottom; none without volume
    QString notice; ///< the render error and the backend notice (bottom, in red)
    /** Difference mode: the units of the values, for the colour bar of the window's symmetric
     *  range at the image's right edge; empty: no colour bar. */
    QString differenceUnits;
    /** The spectrum the view renders from, in words (values, transform, oversampling, gridding
     *  correction for its kernel or none): compare views differ in it. */
    QString spectrum;
    /** Why progressive refinement is off although a target frame rate is set ("in Difference
     *  mode"); empty: not off for a reason. */
    QString progressiveOff;

    // The performance lines.
    core::QualityLevel shown; ///< what the frame on screen rendered with
    /** The slice resolution (the Rendering panel's); a frame shown larger is zoomed in at the
     *  screen's resolution, and the overlay says at what cost. */
    int sliceSize = 0;
    double zoom = 1.0;
    bool gpu = false; ///< rendered by the GPU renderer
    core::VoxelModel voxelModel = core::VoxelModel::Trilinear;
    /** A cone-beam view: its ray model and C-arm line ("LAO 30° CRAN 15°  SID 1000  SOD 750");
     *  empty for a parallel view. */
    QString coneGeometry;
    core::RayModel rayModel = core::RayModel::Trilinear;
    FrameEffects effects;
    FrameStats stats;
    bool interacting = false; ///< a drag: the frame rate the user sees, else the frame time
    bool progressive = false; ///< progressive refinement on (a target frame rate)
    double targetFps = 0;
    int level = 0; ///< the frame's quality level (0: full quality)
    int lastLevel = 0; ///< the coarsest interactive level
    core::DisplayWindow window;
    /** The polychromatic output's line ("polychromatic 80 kVp, 2.5 mm Al: −ln(I/I0)"); empty
     *  for line integrals and Beer-Lambert (their effects line says the latter). */
    QString output;
};

class ViewOverlay {
    Q_DECLARE_TR_FUNCTIONS(ViewOverlay)
public:
    explicit ViewOverlay(OverlayState state) : m_s(std::move(state)) {}

    /** The quantity the polychromatic output shows: "−ln(I/I0)" (show < 0) or material
     *  `show`'s mass thickness ("bone mass thickness (g/cm²)"). */
    static QString polychromaticQuantity(int show);
    /** The tube of a polychromatic output: "80 kVp, 2.5 mm Al" (", 0.1 mm Cu" with copper). */
    static QString polychromaticBeam(double kvp, double filtrationAlMm, double filtrationCuMm);
    /** The overlay's line for `source` (null: none, the output is not polychromatic): the mode,
     *  the tube, the quantity and the noise; or that the material spectra are being prepared. */
    static QString polychromaticLine(const PolychromaticSource* source);

    /** The patient-direction labels of a view of `volume` at the image's left, right, top and
     *  bottom edges ("L", "S", ...; with " (assumed)" when the file states no orientation). */
    static QStringList orientationLabels(const core::Volume& volume, const core::ViewFrame& view);

    /** The box's lines: the title, the performance lines (when shown), the difference note. */
    QString text() const;
    /** fps or frame time, kernel, size, backend, voxel model; progressive level; effects; stage
     *  times; window width and level. */
    QStringList performanceLines() const;
    /** The image effects in words (depth cue, edges, band limit, Beer-Lambert); empty: none. */
    QStringList effectsSummary() const;
    /** The box around text() in widget coordinates; null without text or without an image. */
    QRect box() const;
    /** Where the labels go (left, right, top, bottom): at the image's edges, and below the box
     *  (or right of it in a small view) where they would fall under it. Empty without labels. */
    QList<QRect> labelRects() const;
    /** The overlay's font: the view's, at least 8 pt. */
    QFont font(bool bold = false) const;

    /** Draws all of it with `p` (on the view, or on an image in the tests). */
    void paint(QPainter& p) const;
    /** Where the difference colour bar is drawn; null without one. */
    QRect colourBarRect() const;
    /** The colour bar's labels, top to bottom ("+0.52 mm", "0", "−0.52 mm"); empty without one. */
    QStringList colourBarLabels() const;

private:
    QRect box(const QString& text) const;
    QList<QRect> labelRects(const QRect& avoid) const;
    QString speed() const;
    QString stageLine() const;
    void paintNoImage(QPainter& p) const;
    void paintNotice(QPainter& p) const;
    void paintColourBar(QPainter& p) const;

    OverlayState m_s;
};

} // namespace fvr::ui
