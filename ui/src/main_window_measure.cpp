// The main window's reader's tools: the Measure menu and toolbar (pointer, ruler, angle,
// rectangle and ellipse ROIs, arrow, text, clear), the image's turns and mirrors, and the
// status bar's value under the cursor.
#include <fvr/ui/main_window.h>

#include <QActionGroup>
#include <QLabel>
#include <QMenuBar>
#include <QSettings>
#include <QStatusBar>
#include <QToolBar>

#include <algorithm>

#include <fvr/core/xray/display_window.h>

namespace fvr::ui {

void MainWindow::buildMeasureMenu() {
    QMenu* menu = menuBar()->addMenu(tr("&Measure"));
    // A tool palette down the views' left side, as readers know it: the top row is full (the
    // main and cine toolbars), and a row of its own would not fit a 960 x 540 screen. All of it
    // is in the Measure menu too.
    auto* tb = new QToolBar(tr("Measure"), this);
    tb->setObjectName("toolbar.measure");
    tb->setToolButtonStyle(Qt::ToolButtonTextOnly);
    addToolBar(Qt::LeftToolBarArea, tb);
    auto* group = new QActionGroup(this);
    const std::tuple<MeasureTool, QString, QString> tools[] = {
        {MeasureTool::Pointer, tr("&Pointer"), tr("Rotate, window and pan (Esc)")},
        {MeasureTool::Ruler, tr("&Ruler"), tr("Distance in mm: drag from end to end")},
        {MeasureTool::Angle, tr("&Angle"),
         tr("Angle: drag the first arm to the vertex, then click the second arm's end")},
        {MeasureTool::Rectangle, tr("R&ectangle ROI"),
         tr("Mean, SD, min, max and area of a rectangle")},
        {MeasureTool::Ellipse, tr("E&llipse ROI"), tr("Mean, SD, min, max and area of an ellipse")},
        {MeasureTool::Arrow, tr("Arro&w"), tr("Arrow: drag from the point shown to the tail")},
        {MeasureTool::Text, tr("&Text"), tr("Text annotation: click where it goes")}};
    for (const auto& [tool, name, tip] : tools) {
        QAction* a = menu->addAction(name, this, [this, tool] { setMeasureTool(tool); });
        a->setIconText(QString(name).remove('&').remove(tr(" ROI"))); // short on the toolbar
        a->setCheckable(true);
        a->setChecked(tool == m_measureTool);
        a->setToolTip(tip);
        a->setStatusTip(tip);
        group->addAction(a);
        tb->addAction(a);
        m_measureActions[tool] = a;
    }
    m_measureActions[MeasureTool::Pointer]->setShortcut(QKeySequence(Qt::Key_Escape));
    menu->addSeparator();
    QAction* clear = menu->addAction(tr("&Clear annotations"), this, [this] {
        for (auto* v : m_views) v->measure().clear();
    });
    clear->setIconText(tr("Clear"));
    tb->addAction(clear);
    menu->addSeparator();
    const std::pair<measure::Turn, QString> turns[] = {
        {measure::Turn::FlipHorizontal, tr("Flip &horizontal")},
        {measure::Turn::FlipVertical, tr("Flip &vertical")},
        {measure::Turn::Clockwise, tr("Rotate 90° clock&wise")},
        {measure::Turn::CounterClockwise, tr("Rotate 90° counter-clockw&ise")}};
    for (const auto& [t, name] : turns) menu->addAction(name, this, [this, t] { turnImage(t); });
    // A saved session keeps view 1's annotations (its own group of the session file).
    connect(this, &MainWindow::savingSession, this, [this](QSettings& st) {
        if (!m_views.empty()) saveAnnotations(st, m_views[0]->measure().annotations());
    });
    connect(this, &MainWindow::sessionOpened, this, [this](QSettings& st) {
        if (m_views.empty()) return;
        MeasureLayer& m = m_views[0]->measure();
        m.clear();
        for (Annotation& a : loadAnnotations(st)) m.add(std::move(a));
    });
    m_cursorLabel = new QLabel(this);
    m_cursorLabel->setContentsMargins(8, 0, 4, 0);
    m_cursorLabel->setMinimumWidth(fontMetrics().horizontalAdvance("x 0000  y 0000   -0.0000e+00 "
                                                                   "−ln(I/I0)"));
    statusBar()->addPermanentWidget(m_cursorLabel);
}

void MainWindow::setMeasureTool(MeasureTool tool) {
    m_measureTool = tool;
    for (auto* v : m_views) v->measure().setTool(tool);
    if (auto it = m_measureActions.find(tool); it != m_measureActions.end())
        it->second->setChecked(true);
}

void MainWindow::attachMeasure(ProjectionView* v) {
    v->measure().setTool(m_measureTool);
    connect(&v->measure(), &MeasureLayer::readout, this, [this](const QString& text) {
        if (m_cursorLabel) m_cursorLabel->setText(text);
    });
}

QString MainWindow::cursorReadout() const {
    return m_cursorLabel ? m_cursorLabel->text() : QString();
}

void MainWindow::turnImage(measure::Turn t) {
    if (m_views.empty()) return;
    // View 1 turns; the others follow its view frame (synchronised) and turn their annotations.
    for (std::size_t i = 1; i < m_views.size(); ++i) m_views[i]->measure().turn(t);
    m_views[0]->turnImage(t);
}

} // namespace fvr::ui

namespace fvr::ui {

std::vector<float> MainWindow::withAnnotations(const core::ProjectionImage& image) const {
    std::vector<float> out = image.pixels;
    if (m_views.empty() || m_views[0]->measure().annotations().empty()) return out;
    if (image.width != image.height) return out; // the views render squares
    const QImage mask = m_views[0]->measure().annotationMask(image.width);
    // The brightest value under the window: the ends of the image's range and of the window.
    const core::DisplayWindow& w = m_views[0]->window();
    const auto [lo, hi] = std::minmax_element(out.begin(), out.end());
    float ink = *hi;
    for (double v : {double(*lo), double(*hi), w.low, w.high, 0.0})
        if (w.map(v) > w.map(ink)) ink = float(v);
    for (int y = 0; y < image.height; ++y) {
        const uchar* row = mask.constScanLine(y);
        for (int x = 0; x < image.width; ++x)
            if (row[x]) out[std::size_t(y) * image.width + x] = ink;
    }
    return out;
}

core::DicomOverlay MainWindow::annotationOverlay(int width, int height) const {
    core::DicomOverlay o;
    if (m_views.empty() || m_views[0]->measure().annotations().empty() || width != height) return o;
    const QImage mask = m_views[0]->measure().annotationMask(width);
    o.bits.resize(std::size_t(width) * height);
    for (int y = 0; y < height; ++y) {
        const uchar* row = mask.constScanLine(y);
        for (int x = 0; x < width; ++x) o.bits[std::size_t(y) * width + x] = row[x] ? 1 : 0;
    }
    o.description = "annotations";
    return o;
}

} // namespace fvr::ui
