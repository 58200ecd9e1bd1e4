// The main window's reading tools: Study ▸ DICOM tags…, the Cine menu and toolbar (play, axis,
// step, frame rate) and the cine's exports (MP4 movie, multi-frame DICOM).
#include <fvr/ui/main_window.h>

#include <QActionGroup>
#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QLabel>
#include <QLineEdit>
#include <QMenuBar>
#include <QProgressDialog>
#include <QSignalBlocker>
#include <QSpinBox>
#include <QToolBar>

#include <cmath>

#include <fvr/core/dicom/multiframe_export.h>
#include <fvr/core/io/movie_writer.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/cine_controller.h>
#include <fvr/ui/dicom_tags_dialog.h>

namespace fvr::ui {

namespace {

/** The patient axis `a` in the volume's index frame: the row of index -> patient (LPS) for it. */
core::Vec3 patientAxis(const core::Volume& volume, CineSettings::Axis a) {
    const int row = a == CineSettings::Axis::LeftRight           ? 0
                    : a == CineSettings::Axis::AnteriorPosterior ? 1
                                                                 : 2;
    const auto& d = volume.direction;
    return {d[0][row], d[1][row], d[2][row]};
}

/** The Cine toolbar's controls: axis, step, frame rate, loop. */
void addCineControls(QToolBar* tb, CineController* cine) {
    auto* axis = new QComboBox;
    axis->setObjectName("cine.axis");
    axis->addItems({QObject::tr("S-I axis"), QObject::tr("L-R axis"), QObject::tr("A-P axis")});
    axis->setToolTip(QObject::tr("The patient axis the view turns about"));
    auto* step = new QDoubleSpinBox;
    step->setObjectName("cine.step");
    step->setRange(-90.0, 90.0);
    step->setDecimals(1);
    step->setSuffix(QObject::tr("°/frame"));
    step->setValue(cine->settings().stepDegrees);
    auto* fps = new QSpinBox;
    fps->setObjectName("cine.fps");
    fps->setRange(1, 60);
    fps->setSuffix(QObject::tr(" fps"));
    fps->setValue(int(cine->settings().fps));
    auto* loop = new QCheckBox(QObject::tr("Loop"));
    loop->setObjectName("cine.loop");
    loop->setToolTip(QObject::tr("Off: one full 360° turn, then stop"));
    loop->setChecked(cine->settings().loop);
    const auto apply = [=] {
        CineSettings s = cine->settings();
        s.axis = CineSettings::Axis(axis->currentIndex());
        s.stepDegrees = step->value();
        s.fps = fps->value();
        s.loop = loop->isChecked();
        cine->setSettings(s);
    };
    QObject::connect(axis, &QComboBox::currentIndexChanged, cine, apply);
    QObject::connect(step, &QDoubleSpinBox::valueChanged, cine, apply);
    QObject::connect(fps, &QSpinBox::valueChanged, cine, apply);
    QObject::connect(loop, &QCheckBox::toggled, cine, apply);
    for (QWidget* w : std::initializer_list<QWidget*>{axis, step, fps, loop}) tb->addWidget(w);
}

} // namespace

void MainWindow::buildReaderMenus() {
    m_cine = new CineController(
        [this]() -> std::optional<core::ViewFrame> {
            if (m_views.empty() || !m_study->volume()) return std::nullopt;
            return m_views[0]->viewFrame();
        },
        [this](const core::ViewFrame& f) {
            for (auto* v : m_views) v->setViewFrame(f);
            showCArmAngles(f);
        },
        [this](CineSettings::Axis a) -> std::optional<core::Vec3> {
            if (!m_study->volume()) return std::nullopt;
            return patientAxis(*m_study->volume(), a);
        },
        this);
    QMenu* studyMenu = menuBar()->addMenu(tr("&Study"));
    QAction* tags = studyMenu->addAction(tr("DICOM &tags…"), this, [this] { showDicomTags(); });
    tags->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_T));

    QMenu* cineMenu = menuBar()->addMenu(tr("&Cine"));
    QToolBar* tb = addToolBar(tr("Cine"));
    tb->setObjectName("toolbar.cine");
    QAction* play = cineMenu->addAction(tr("&Play / pause"));
    play->setObjectName("cine.play");
    play->setCheckable(true);
    play->setShortcut(QKeySequence(Qt::Key_Space));
    play->setToolTip(tr("Play or pause the rotation (Space)"));
    play->setIconText(tr("Play"));
    connect(play, &QAction::triggered, m_cine, [this, play](bool on) {
        on ? m_cine->play() : m_cine->pause();
        const QSignalBlocker block(play);
        play->setChecked(m_cine->playing()); // no study: it does not start
    });
    connect(m_cine, &CineController::playingChanged, play, [play](bool on) {
        const QSignalBlocker block(play);
        play->setChecked(on);
        play->setText(on ? tr("&Pause") : tr("&Play"));
        play->setIconText(on ? tr("Pause") : tr("Play"));
    });
    tb->addAction(play);
    addCineControls(tb, m_cine);
    cineMenu->addSeparator();
    QAction* movie = cineMenu->addAction(tr("Save as &movie (MP4)…"), this, [this] {
        const QString path = QFileDialog::getSaveFileName(
            this, tr("Export movie"), exportFolder() + "/cine.mp4", tr("MP4 movie (*.mp4)"));
        if (!path.isEmpty()) exportMovie(path);
    });
    QAction* dicom = cineMenu->addAction(tr("Save as multi-frame &DICOM…"), this, [this] {
        const QString path =
            QFileDialog::getSaveFileName(this, tr("Export cine as multi-frame DICOM"),
                                         exportFolder() + "/cine.dcm", tr("DICOM (*.dcm)"));
        if (!path.isEmpty()) exportCineDicom(path);
    });
    for (QAction* a : {play, movie, dicom, tags}) {
        a->setEnabled(false);
        connect(m_study.get(), &StudyController::studyLoaded, a, [a] { a->setEnabled(true); });
    }
    // A new study: the cine stops, the tag browser shows the new series.
    connect(m_study.get(), &StudyController::studyLoaded, this, [this] {
        m_cine->pause();
        if (m_tags && m_tags->isVisible()) showDicomTags();
    });
}

DicomTagsDialog* MainWindow::showDicomTags() {
    if (!m_tags) m_tags = new DicomTagsDialog(this);
    const auto& series = m_study->series();
    if (series)
        m_tags->setFiles(series->files,
                         QString::fromStdString(series->description.empty() ? series->seriesUid
                                                                            : series->description));
    else
        m_tags->setFiles({}, {});
    m_tags->show();
    m_tags->raise();
    m_tags->activateWindow();
    m_tags->filterEdit()->setFocus(); // type to search at once
    return m_tags;
}

std::vector<core::ProjectionImage> MainWindow::renderCineTurn(const QString& what) {
    std::vector<core::ProjectionImage> frames;
    if (m_views.empty() || !m_study->volume()) {
        message(tr("%1: no study open").arg(what), true);
        return frames;
    }
    m_cine->pause();
    ProjectionView* v = m_views[0];
    const core::ViewFrame start = v->viewFrame();
    const int n = m_cine->settings().framesPerTurn();
    QProgressDialog progress(tr("%1: rendering %2 frames…").arg(what).arg(n), tr("Cancel"), 0, n,
                             this);
    progress.setWindowModality(Qt::WindowModal);
    progress.setMinimumDuration(300);
    for (int k = 0; k < n; ++k) {
        progress.setValue(k);
        if (progress.wasCanceled()) {
            frames.clear();
            message(tr("%1 cancelled").arg(what), true);
            break;
        }
        v->setViewFrame(*m_cine->frameAt(start, k));
        auto p = v->projection();
        if (!p) {
            frames.clear();
            message(tr("%1 failed: frame %2 did not render (%3)")
                        .arg(what)
                        .arg(k + 1)
                        .arg(v->renderError()),
                    true);
            break;
        }
        frames.push_back(std::move(*p));
    }
    progress.setValue(n);
    v->setViewFrame(start);
    return frames;
}

bool MainWindow::exportMovie(const QString& path) {
    const std::vector<core::ProjectionImage> frames = renderCineTurn(tr("Movie export"));
    if (frames.empty()) return false;
    const core::DisplayWindow w = m_views[0]->window();
    try {
        const int W = frames[0].width, H = frames[0].height;
        core::MovieWriter movie(path.toStdString(), W, H, m_cine->settings().fps);
        std::vector<std::uint8_t> grey(std::size_t(W) * H);
        for (const core::ProjectionImage& f : frames) {
            // Through view 1's window, as the screen shows it.
            for (std::size_t i = 0; i < grey.size(); ++i)
                grey[i] = std::uint8_t(std::lround(255.0 * w.map(f.pixels[i])));
            movie.addFrame(grey.data());
        }
        movie.finish();
    } catch (const std::exception& e) {
        message(tr("Could not export the movie: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    message(tr("Exported movie %1 (%2 frames of %3 × %3, %4° apart about the %5 axis, %6 fps, "
               "H.264)")
                .arg(path)
                .arg(frames.size())
                .arg(frames[0].width)
                .arg(m_cine->settings().stepDegrees)
                .arg(QString::fromLatin1(m_cine->settings().axisName()))
                .arg(m_cine->settings().fps));
    return true;
}

bool MainWindow::exportCineDicom(const QString& path) {
    std::vector<core::ProjectionImage> frames = renderCineTurn(tr("Multi-frame DICOM export"));
    if (frames.empty()) return false;
    const CineSettings& s = m_cine->settings();
    core::CineDescription cine{1000.0 / s.fps, s.stepDegrees, s.axisName()};
    try {
        if (const core::Transmission t = currentTransmission(); t.active())
            for (core::ProjectionImage& f : frames) core::applyTransmission(f.pixels, t);
        const core::DicomExportInfo info = dicomExportInfo();
        core::writeDicomMultiframe(path.toStdString(), frames, cine, info);
    } catch (const std::exception& e) {
        message(tr("Could not export: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    message(tr("Exported multi-frame DICOM %1 (%2 frames, frame time %3 ms, %4)")
                .arg(path)
                .arg(frames.size())
                .arg(cine.frameTimeMs, 0, 'g', 4)
                .arg(exportedQuantity()));
    return true;
}

} // namespace fvr::ui
