#pragma once
/** The reader's tools on a ProjectionView: ruler, angle, rectangle and ellipse ROI statistics,
 *  arrow and text annotations, the value under the cursor and a scale bar. The annotations are
 *  kept in image coordinates (a fraction of the image's side), so zoom and pan move them with
 *  the image; their handles can be dragged and a selected one deleted (Delete). The layer
 *  filters the view's mouse and key events: a drawing tool takes the left button, the pointer
 *  leaves it to the view (rotation, window), and a handle is grabbed with any tool. */
#include <QImage>
#include <QObject>
#include <QPointF>
#include <QString>

#include <functional>
#include <optional>
#include <vector>

#include <fvr/core/render/projection.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/measure_geometry.h>
#include <fvr/ui/view_settings.h>

class QPainter;
class QSettings;

namespace fvr::ui {

class ProjectionView;

enum class MeasureTool { Pointer, Ruler, Angle, Rectangle, Ellipse, Arrow, Text };

struct Annotation {
    enum class Kind { Ruler, Angle, Rectangle, Ellipse, Arrow, Text };
    Kind kind = Kind::Ruler;
    /** Image coordinates as fractions of the image's side (0..1, rows down). Ruler: the two
     *  ends; Angle: the end of the first arm, the vertex, the end of the second; Rectangle and
     *  Ellipse: two opposite corners; Arrow: the head, then the tail; Text: its anchor. */
    std::vector<measure::Point> points;
    QString text; ///< Text: what it says
};

/** Writes the annotations into group "annotations" of `s` (a saved session): each one's kind,
 *  points (image fractions, 17 digits) and text. */
void saveAnnotations(QSettings& s, const std::vector<Annotation>& items);
/** Reads what saveAnnotations() wrote; an entry of unknown kind or with the wrong number of
 *  points is left out. */
std::vector<Annotation> loadAnnotations(QSettings& s);

class MeasureLayer : public QObject {
    Q_OBJECT
public:
    explicit MeasureLayer(ProjectionView* view);

    void setTool(MeasureTool tool);
    MeasureTool tool() const { return m_tool; }

    const std::vector<Annotation>& annotations() const { return m_items; }
    /** Adds an annotation (not selected: a text is placed, then left alone). */
    void add(Annotation a);
    void clear();
    void remove(int index);
    /** The annotation whose handle was last grabbed or that was last drawn (-1: none). */
    int selected() const { return m_selected; }
    void select(int index);

    /** The image the measurements read (the view's projection, fetched again when the view
     *  rendered a new frame). Empty without a study. */
    const std::optional<core::ProjectionImage>& image();
    /** Pixel size (mm) of the measured image; 0 when unknown. */
    double pixelMm();
    /** A cone-beam view: lengths and areas are at the isocentre plane. */
    bool atIsocentre() const;
    /** A ruler's length in mm, an angle's degrees (nothing for other kinds). */
    std::optional<double> lengthMm(int index);
    std::optional<double> angleDeg(int index) const;
    std::optional<measure::RoiStats> roiStats(int index);
    /** What the view shows at an image point, with units ("12.3 mm", "0.41 I/I0"). */
    std::optional<double> shownValue(measure::Point imagePx);
    QString units() const;
    /** The annotation's label as drawn ("24.0 mm at isocentre", "37.5°", the ROI's lines). */
    QString label(int index);
    /** The status bar's readout for a widget position: image pixel and value with units. */
    QString readoutAt(QPointF widgetPos);
    /** The scale bar: its length (mm) and its label; 0 without an image. */
    double scaleBarMm();
    QString scaleBarLabel();

    /** Widget <-> image pixels (continuous, see measure_geometry.h) of the current display. */
    QPointF toWidget(measure::Point imagePx) const;
    measure::Point toImage(QPointF widgetPos) const;
    int imageSide() const;

    /** Draws the annotations, their labels and the scale bar on the view (widget coordinates). */
    void paint(QPainter& p);
    /** The annotations and their labels drawn at the image's own pixels (side x side): white
     *  on black, no antialiasing. Exports burn it in or store it as an overlay plane. */
    QImage annotationMask(int side);
    /** The annotations follow the image when it is turned or mirrored. */
    void turn(measure::Turn t);

    bool eventFilter(QObject* watched, QEvent* event) override;

signals:
    void changed();
    /** The value under the cursor (empty: the cursor left the image). */
    void readout(const QString& text);

private:
    measure::Point toFraction(measure::Point px) const;
    measure::Point toPixels(measure::Point f) const;
    /** The annotation and point whose handle lies within reach of a widget position. */
    std::optional<std::pair<int, int>> handleAt(QPointF widgetPos) const;
    bool mousePress(QPointF pos, Qt::KeyboardModifiers mods);
    bool mouseMove(QPointF pos, Qt::MouseButtons buttons);
    bool mouseRelease(QPointF pos);
    /** Draws one annotation with a transform from image pixels to the painter's coordinates. */
    void paintItem(QPainter& p, int index, const std::function<QPointF(measure::Point)>& map,
                   double scale, bool handles);
    /** Soon after (not in paintGL): the view's frame again where needsFrame(). */
    void refreshSoon();
    /** m_image is the view's frame on screen, in the quantity shown. */
    bool imageCurrent() const;
    /** Something on screen needs the current frame: ROI statistics, or a pixel size that may
     *  have changed with the settings. */
    bool needsFrame() const;

    ProjectionView* m_view;
    MeasureTool m_tool = MeasureTool::Pointer;
    std::vector<Annotation> m_items;
    int m_selected = -1;
    /** The drag in progress: the annotation and the point it moves (-1: none). */
    int m_dragItem = -1, m_dragPoint = -1;
    bool m_angleSecondArm = false; ///< an angle waits for its second arm's end
    std::optional<core::ProjectionImage> m_image;
    int m_imageFrame = -1; ///< the view's framesRendered() of m_image
    ViewSettings m_imageSettings; ///< the view's settings for m_image
    core::Transmission m_imageTransmission; ///< applied to m_image (Beer-Lambert)
    bool m_refreshQueued = false;
    bool m_painting = false; ///< in paint(): image() fetches nothing (no render in paintGL)
};

} // namespace fvr::ui
