#include <fvr/ui/main_window.h>

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QClipboard>
#include <QCloseEvent>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QGridLayout>
#include <QInputDialog>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QProgressDialog>
#include <QPushButton>
#include <QSaveFile>
#include <QScrollArea>
#include <QSettings>
#include <QSpinBox>
#include <QStatusBar>
#include <QTime>
#include <QToolBar>
#include <QVBoxLayout>

#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/image_metrics.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/app_info.h>

namespace fvr::ui {

namespace {
const int kSizes[] = {128, 256, 512, 1024, 2048};
const double kOversampling[] = {1.0, 1.25, 1.5, 2.0};
constexpr int kMaxRecent = 8;
} // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent), m_study(std::make_unique<StudyController>()) {
    setWindowTitle(QString::fromUtf8(applicationName()));
    setAcceptDrops(true);
    setDockNestingEnabled(true);
    m_viewSettings.assign(4, ViewSettings{});
    const core::Kernel compareKernels[4] = {core::Kernel::Linear, core::Kernel::CatmullRom, core::Kernel::Nearest,
                                            core::Kernel::Sinc4};
    for (int i = 0; i < 4; ++i) m_viewSettings[i].kernel = compareKernels[i];
    buildViews();
    buildDocks();
    buildMenus();

    connect(m_study.get(), &StudyController::progress, this, [this](double f, const QString& stage) {
        m_progress->setVisible(true);
        m_cancel->setVisible(true);
        m_progress->setValue(int(std::lround(f * 1000)));
        m_progress->setFormat(QStringLiteral("%1 %p%").arg(stage));
    });
    connect(m_study.get(), &StudyController::studyLoaded, this, &MainWindow::onStudyLoaded);
    connect(m_study.get(), &StudyController::spectrumReady, this, &MainWindow::onSpectrumReady);
    connect(m_study.get(), &StudyController::failed, this, [this](const QString& title, const QString& details) {
        m_progress->setVisible(false);
        m_cancel->setVisible(false);
        message(title + ": " + details, true);
        auto* box = new QMessageBox(QMessageBox::Warning, title, details, QMessageBox::Ok, this);
        box->setAttribute(Qt::WA_DeleteOnClose);
        box->setTextInteractionFlags(Qt::TextSelectableByMouse);
        box->setModal(false);
        box->show();
    });
    connect(m_study.get(), &StudyController::cancelled, this, [this] {
        m_progress->setVisible(false);
        m_cancel->setVisible(false);
        message(tr("Cancelled; the previous study stays open."));
    });
    connect(m_study.get(), &StudyController::warningsChanged, this, [this](const QStringList& w) {
        for (const auto& s : w) message(tr("Warning: %1").arg(s), true);
        updateStudyInfo();
    });
    connect(m_study.get(), &StudyController::seriesChoiceNeeded, this,
            [this](const StudySource& src, const QStringList& keys, const QStringList& labels) {
                m_progress->setVisible(false);
                m_cancel->setVisible(false);
                bool ok = false;
                const QString pick = QInputDialog::getItem(this, tr("Choose a series"),
                                                           tr("%1 holds several series:").arg(src.path), labels, 0,
                                                           false, &ok);
                if (!ok) return;
                StudySource chosen = src;
                chosen.seriesKey = keys.at(labels.indexOf(pick));
                openStudy(chosen);
            });

    QSettings settings;
    restoreGeometry(settings.value("window/geometry").toByteArray());
    restoreState(settings.value("window/state").toByteArray());
    if (!settings.contains("window/geometry")) resize(1400, 900);
    rebuildRecentMenu();
}

MainWindow::~MainWindow() {
    if (m_accuracyWorker.joinable()) m_accuracyWorker.join();
}

void MainWindow::measureAccuracy() {
    if (m_views.empty() || !m_study->volume() || !m_study->spectrum()) return;
    if (m_accuracyWorker.joinable()) {
        if (!m_accuracyDone.load()) {
            message(tr("The accuracy measurement is still running"));
            return;
        }
        m_accuracyWorker.join();
    }
    if (m_views[0]->effects().filter.active()) {
        message(tr("The accuracy readout compares with ray casting, which has no slice filters: turn edge "
                   "enhancement and the band limit off to measure."),
                true);
        return;
    }
    auto fvr = m_views[0]->projection();
    if (!fvr) return;
    const auto volume = m_study->volume();
    // The ray caster with the same voxel model, depth weighting and pixel sampling as the frame.
    const core::RenderParams rendered = m_views[0]->renderParams(fvr->size, m_views[0]->settings().kernel);
    const core::SpatialProjectorOptions options = core::matchingProjectorOptions(rendered, m_study->spectrum()->mapping);
    const QString reference = QString::fromStdString(core::describeProjector(options, rendered.voxelModel));
    const core::ViewFrame view = fvr->view;
    const core::ImageGeometry geom{fvr->size, fvr->pixelSize};
    message(tr("Measuring accuracy: %1 of the same view, in the background…").arg(reference));
    m_accuracyDone.store(false);
    m_accuracyWorker = std::thread([this, volume, options, reference, view, geom, fvr = *fvr] {
        double psnr = 0, rel = 0;
        try {
            core::SpatialProjector sp(*volume, options);
            const core::ImageComparison c = core::compareImages(fvr.pixels, sp.project(view, geom).pixels);
            psnr = c.psnr;
            rel = c.relRmse;
        } catch (const std::exception& e) {
            const QString what = QString::fromUtf8(e.what());
            QMetaObject::invokeMethod(this, [this, what] { message(tr("Accuracy measurement failed: %1").arg(what), true); },
                                      Qt::QueuedConnection);
            m_accuracyDone.store(true);
            return;
        }
        QMetaObject::invokeMethod(this, [this, psnr, rel, reference] {
            message(tr("Accuracy of view 1 against %1: PSNR %2 dB, relative RMSE %3 %")
                        .arg(reference)
                        .arg(psnr, 0, 'f', 2)
                        .arg(rel * 100.0, 0, 'f', 2));
            emit accuracyMeasured(psnr, rel);
        }, Qt::QueuedConnection);
        m_accuracyDone.store(true);
    });
}

void MainWindow::buildViews() {
    m_viewHost = new QWidget(this);
    m_viewGrid = new QGridLayout(m_viewHost);
    m_viewGrid->setContentsMargins(0, 0, 0, 0);
    m_viewGrid->setSpacing(2);
    setCentralWidget(m_viewHost);
    setCompareCount(1);
}

void MainWindow::setCompareCount(int n) {
    n = (n >= 4) ? 4 : (n >= 2 ? 2 : 1);
    if (n > 1 && m_deapodize && m_deapodize->isChecked()) {
        // A deapodized spectrum serves one kernel; the comparison needs them all.
        message(tr("Compare mode: gridding correction turned off so that each view can use its own kernel."));
        m_deapodize->setChecked(false);
    }
    const core::ViewFrame frame = m_views.empty() ? core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0}) : m_views[0]->viewFrame();
    const std::optional<core::DisplayWindow> window =
        m_views.empty() ? std::nullopt : std::optional<core::DisplayWindow>(m_views[0]->window());
    if (m_compareCount == 1 && !m_views.empty()) {
        m_viewSettings[0] = m_views[0]->settings();
        // The other views start with the other kernels, so the comparison shows something.
        const core::Kernel order[] = {core::Kernel::Linear, core::Kernel::Nearest, core::Kernel::Sinc4,
                                      core::Kernel::CatmullRom, core::Kernel::BSpline};
        int slot = 1;
        for (core::Kernel k : order)
            if (k != m_viewSettings[0].kernel && slot < 4)
                m_viewSettings[slot++] = {k, m_viewSettings[0].size, m_viewSettings[0].voxelModel};
    }
    for (auto* v : m_views) v->deleteLater();
    m_views.clear();
    m_compareCount = n;
    for (int i = 0; i < n; ++i) {
        auto* v = new ProjectionView(m_viewHost);
        ViewSettings s = m_viewSettings[i];
        if (n == 1) s = m_viewSettings[0];
        v->setSettings(s);
        v->setViewFrame(frame);
        v->setOverlayVisible(m_overlayAction ? m_overlayAction->isChecked() : true);
        if (m_depthCue) v->setEffects(currentEffects());
        if (m_targetFps) v->setTargetFps(m_difference ? 0 : m_targetFps->value());
        connect(v, &ProjectionView::interactionChanged, this, [this, v](bool on) {
            for (auto* o : m_views)
                if (o != v) o->setInteracting(on); // synchronised views follow at their own level
        });
        if (n > 1) v->setTitle(viewTitle(i, s));
        m_viewGrid->addWidget(v, i / 2, i % 2);
        if (m_study->spectrum()) v->setStudy(m_study->volume(), m_study->spectrum());
        // After setStudy (a new view's first study would reset the window to an auto window
        // computed whenever it first paints, possibly after the user changed the output).
        if (window) v->setWindow(*window);
        connect(v, &ProjectionView::viewFrameChanged, this, [this, v](const core::ViewFrame& f) {
            if (m_syncing) return;
            m_syncing = true;
            for (auto* o : m_views)
                if (o != v) o->setViewFrame(f);
            m_syncing = false;
        });
        connect(v, &ProjectionView::windowChanged, this, [this, v](const core::DisplayWindow& w) {
            if (m_syncing) return;
            m_syncing = true;
            if (v == m_views.front() || !m_difference) {
                for (auto* o : m_views)
                    if (o != v && !(m_difference && o != m_views.front())) o->setWindow(w);
                syncWindowToPanel(w);
            }
            m_syncing = false;
        });
        connect(v, &ProjectionView::backendChanged, this, [this](bool gpu, const QString& notice) {
            if (m_backend) m_backend->setText(gpu ? tr("Renderer: GPU") : tr("Renderer: CPU"));
            if (!notice.isEmpty()) message(notice, true);
        });
        m_views.push_back(v);
    }
    setDifferenceMode(m_difference);
    if (m_compareSlot) {
        m_compareSlot->clear();
        m_compareSlot->addItem(tr("All views"));
        for (int i = 0; i < n && n > 1; ++i) m_compareSlot->addItem(tr("View %1").arg(i + 1));
        m_compareSlot->setEnabled(n > 1);
    }
}

void MainWindow::setDifferenceMode(bool on) {
    m_difference = on;
    for (std::size_t i = 1; i < m_views.size(); ++i) m_views[i]->setDifferenceReference(on ? m_views[0] : nullptr);
    // Differences compare full-quality frames: no progressive levels while they are shown.
    for (auto* v : m_views) v->setTargetFps(on || !m_targetFps ? 0 : m_targetFps->value());
    // Back from differences: the views take view 1's window again (transmission included).
    if (!on && !m_views.empty())
        for (std::size_t i = 1; i < m_views.size(); ++i) m_views[i]->setWindow(m_views[0]->window());
}

void MainWindow::buildDocks() {
    // Study
    auto* studyDock = new QDockWidget(tr("Study"), this);
    studyDock->setObjectName("dock.study");
    m_studyInfo = new QLabel(tr("No study"), studyDock);
    m_studyInfo->setWordWrap(true);
    m_studyInfo->setTextInteractionFlags(Qt::TextSelectableByMouse);
    m_studyInfo->setAlignment(Qt::AlignTop | Qt::AlignLeft);
    m_studyInfo->setMargin(6);
    auto* studyScroll = new QScrollArea(studyDock);
    studyScroll->setWidget(m_studyInfo);
    studyScroll->setWidgetResizable(true);
    studyScroll->setFrameShape(QFrame::NoFrame);
    studyScroll->setMinimumHeight(170);
    studyDock->setWidget(studyScroll);
    addDockWidget(Qt::RightDockWidgetArea, studyDock);

    // Rendering
    auto* renderDock = new QDockWidget(tr("Rendering"), this);
    renderDock->setObjectName("dock.rendering");
    auto* rw = new QWidget(renderDock);
    auto* rf = new QFormLayout(rw);
    m_compareSlot = new QComboBox(rw);
    m_compareSlot->addItem(tr("All views"));
    m_compareSlot->setEnabled(false);
    rf->addRow(tr("Applies to"), m_compareSlot);
    m_kernel = new QComboBox(rw);
    for (core::Kernel k : core::allKernels()) m_kernel->addItem(QString::fromUtf8(core::kernelName(k)), int(k));
    rf->addRow(tr("Interpolation"), m_kernel);
    m_size = new QComboBox(rw);
    for (int s : kSizes) m_size->addItem(QStringLiteral("%1 × %1").arg(s), s);
    rf->addRow(tr("Slice resolution"), m_size);
    m_voxelModel = new QComboBox(rw);
    m_voxelModel->addItem(tr("Trilinear (as a DRR ray caster)"), int(core::VoxelModel::Trilinear));
    m_voxelModel->addItem(tr("Cubic B-spline through the voxels"), int(core::VoxelModel::BSpline));
    m_voxelModel->addItem(tr("Band-limited (sharpest, rings)"), int(core::VoxelModel::BandLimited));
    m_voxelModel->setToolTip(tr("What lies between the voxels. Trilinear: the projection a trilinear DRR ray caster "
                                "computes, no ringing at the scan ends. Band-limited: the plain Fourier image, the "
                                "sharpest, but it rings (stripes, negative values) where the scan ends inside the body "
                                "and between coarse slices. Same spectrum: changing it costs no preprocessing."));
    rf->addRow(tr("Voxel model"), m_voxelModel);
    m_transform = new QComboBox(rw);
    m_transform->addItem(tr("FFT (complex half spectrum)"), int(core::TransformKind::Fft));
    m_transform->addItem(tr("FHT (Hartley)"), int(core::TransformKind::Fht));
    rf->addRow(tr("Transform"), m_transform);
    m_oversampling = new QComboBox(rw);
    for (double f : kOversampling) m_oversampling->addItem(QStringLiteral("%1×").arg(f), f);
    rf->addRow(tr("Oversampling"), m_oversampling);
    m_values = new QComboBox(rw);
    m_values->addItem(tr("Attenuation μ (mm)"), int(core::ValueMapping::Mu));
    m_values->addItem(tr("Bone-enhanced μ (mm)"), int(core::ValueMapping::MuBone));
    m_values->addItem(tr("Raw values (value × mm)"), int(core::ValueMapping::Raw));
    m_values->setToolTip(tr("What the projection integrates. μ = μ_water (1 + HU/1000), clipped at 0; bone-enhanced "
                            "makes the slope %1× steeper above %2 HU (bone stands out as on a low-kV film). The "
                            "transform is linear only in these values: a change preprocesses again in the background.")
                             .arg(core::kBoneGain)
                             .arg(core::kBoneThresholdHu));
    rf->addRow(tr("Values"), m_values);
    m_deapodize = new QCheckBox(tr("Gridding correction (deapodize)"), rw);
    m_deapodize->setToolTip(tr("Divide the volume by the kernel's Fourier transform before the 3D FFT, as "
                               "gridding codes do: Kaiser-Bessel with 1.25× oversampling is then more accurate than "
                               "ray casting. The spectrum is made for one kernel; changing the kernel preprocesses again."));
    rf->addRow(QString(), m_deapodize);
    m_memory = new QLabel(rw);
    rf->addRow(tr("Spectrum memory"), m_memory);
    m_targetFps = new QSpinBox(rw);
    m_targetFps->setRange(0, 240);
    m_targetFps->setSuffix(tr(" fps"));
    m_targetFps->setSpecialValueText(tr("off (always full quality)"));
    m_targetFps->setToolTip(tr("Progressive refinement: while you rotate, frames render at a lower slice resolution "
                               "(or with linear interpolation when the spectrum allows) to hold this frame rate; "
                               "the full-quality frame follows when you let go. The overlay shows the level."));
    rf->addRow(tr("Interactive target"), m_targetFps);
    m_pixelAperture = new QCheckBox(tr("Detector pixels integrate over their area"), rw);
    m_pixelAperture->setToolTip(tr("Off: each pixel samples the projection at its centre, as ray casters do. On: each "
                                   "pixel averages the projection over its area, as a detector does (less aliasing "
                                   "when the pixels are coarser than the voxels)."));
    rf->addRow(QString(), m_pixelAperture);
    m_clip = new QCheckBox(tr("Clip to the volume (no ghosts outside it)"), rw);
    m_clip->setToolTip(tr("Pixels whose ray misses the volume are exactly 0 in a projection; Fourier rendering puts "
                          "the kernel's ghost copies and ringing there. On: those pixels show 0."));
    rf->addRow(QString(), m_clip);
    m_nonNegative = new QCheckBox(tr("No negative line integrals"), rw);
    m_nonNegative->setToolTip(tr("For values that are never negative (attenuation, or raw data without negative "
                                 "values) no line integral is: what is left of the interpolation's ringing below 0 "
                                 "is shown as 0. No effect on raw Hounsfield units."));
    rf->addRow(QString(), m_nonNegative);
    renderDock->setWidget(rw);
    addDockWidget(Qt::RightDockWidgetArea, renderDock);

    // Display
    auto* displayDock = new QDockWidget(tr("Display"), this);
    displayDock->setObjectName("dock.display");
    auto* dw = new QWidget(displayDock);
    auto* df = new QFormLayout(dw);
    m_preset = new QComboBox(dw);
    m_preset->addItems({tr("Auto (0.5–99.5 %)"), tr("Full range"), tr("Bone (upper 45 %)"), tr("Soft tissue (10–70 %)")});
    df->addRow(tr("Preset"), m_preset);
    m_width = new QDoubleSpinBox(dw);
    m_width->setDecimals(3);
    m_width->setRange(1e-6, 1e12);
    m_width->setKeyboardTracking(false);
    df->addRow(tr("Window width"), m_width);
    m_level = new QDoubleSpinBox(dw);
    m_level->setDecimals(3);
    m_level->setRange(-1e12, 1e12);
    m_level->setKeyboardTracking(false);
    df->addRow(tr("Window level"), m_level);
    m_invert = new QCheckBox(tr("Invert"), dw);
    m_invert->setToolTip(tr("Line integrals: bone dark. Transmitted intensity: the film look (bone white) when on, "
                            "the fluoroscopy look (bone dark) when off."));
    df->addRow(QString(), m_invert);
    auto* autoBtn = new QPushButton(tr("Auto window"), dw);
    df->addRow(QString(), autoBtn);
    auto* hint = new QLabel(tr("<small>Left drag: rotate · wheel: zoom · middle drag: pan · right drag or "
                               "Ctrl+left: window/level · 1–6: AP, PA, left, right, head, feet · R: reset</small>"),
                            dw);
    hint->setWordWrap(true);
    df->addRow(hint);
    displayDock->setWidget(dw);
    addDockWidget(Qt::RightDockWidgetArea, displayDock);

    // X-ray image: Beer-Lambert output, depth cueing, spectral filters
    auto* xrayDock = new QDockWidget(tr("X-ray"), this);
    xrayDock->setObjectName("dock.xray");
    auto* xw = new QWidget(xrayDock);
    auto* xf = new QFormLayout(xw);
    m_output = new QComboBox(xw);
    m_output->addItem(tr("Line integrals"), 0);
    m_output->addItem(tr("Transmitted intensity (Beer-Lambert)"), 1);
    m_output->setToolTip(tr("Transmitted intensity = exposure × exp(−μ_water × line integral of μ/μ_water): what a "
                            "detector records. Needs attenuation values (μ or bone-enhanced μ)."));
    xf->addRow(tr("Output"), m_output);
    m_energy = new QDoubleSpinBox(xw);
    m_energy->setRange(20.0, 150.0);
    m_energy->setDecimals(0);
    m_energy->setSuffix(tr(" keV"));
    m_energy->setKeyboardTracking(false);
    m_energy->setToolTip(tr("Effective photon energy: sets μ_water (NIST XCOM, water)"));
    xf->addRow(tr("Energy"), m_energy);
    m_muWater = new QLabel(xw);
    xf->addRow(tr("μ water"), m_muWater);
    m_exposure = new QDoubleSpinBox(xw);
    m_exposure->setRange(0.05, 50.0);
    m_exposure->setDecimals(2);
    m_exposure->setSingleStep(0.1);
    m_exposure->setKeyboardTracking(false);
    m_exposure->setToolTip(tr("Relative exposure (mAs): the unattenuated beam reaches this fraction of full scale"));
    xf->addRow(tr("Exposure"), m_exposure);
    m_depthCue = new QSpinBox(xw);
    m_depthCue->setRange(0, 100);
    m_depthCue->setSuffix(tr(" %"));
    m_depthCue->setSpecialValueText(tr("off"));
    m_depthCue->setToolTip(tr("Depth cueing in the frequency domain (Totsuka & Levoy): structures at the back of the "
                              "volume weigh up to this much less than those in front. Needs linear interpolation or "
                              "better."));
    xf->addRow(tr("Depth cueing"), m_depthCue);
    m_sharpen = new QDoubleSpinBox(xw);
    m_sharpen->setRange(0.0, 10.0);
    m_sharpen->setSingleStep(0.25);
    m_sharpen->setSpecialValueText(tr("off"));
    m_sharpen->setKeyboardTracking(false);
    m_sharpen->setToolTip(tr("Edge enhancement (unsharp mask): image + amount × (image − Gaussian blur), applied to "
                             "the 2D slice before the inverse transform (free per frame)"));
    xf->addRow(tr("Edge enhancement"), m_sharpen);
    m_sharpenRadius = new QDoubleSpinBox(xw);
    m_sharpenRadius->setRange(0.1, 50.0);
    m_sharpenRadius->setSuffix(tr(" mm"));
    m_sharpenRadius->setSingleStep(0.5);
    m_sharpenRadius->setKeyboardTracking(false);
    xf->addRow(tr("Edge radius (σ)"), m_sharpenRadius);
    m_bandLimit = new QDoubleSpinBox(xw);
    m_bandLimit->setRange(0.0, 20.0);
    m_bandLimit->setDecimals(2);
    m_bandLimit->setSingleStep(0.05);
    m_bandLimit->setSuffix(tr(" lp/mm"));
    m_bandLimit->setSpecialValueText(tr("off"));
    m_bandLimit->setKeyboardTracking(false);
    m_bandLimit->setToolTip(tr("Band limit: order-8 Butterworth low-pass on the slice, −3 dB at this frequency"));
    xf->addRow(tr("Band limit"), m_bandLimit);
    xrayDock->setWidget(xw);
    addDockWidget(Qt::RightDockWidgetArea, xrayDock);
    tabifyDockWidget(displayDock, xrayDock);
    displayDock->raise();

    // Messages
    auto* msgDock = new QDockWidget(tr("Messages"), this);
    msgDock->setObjectName("dock.messages");
    m_messages = new QPlainTextEdit(msgDock);
    m_messages->setReadOnly(true);
    m_messages->setMaximumBlockCount(2000);
    msgDock->setWidget(m_messages);
    addDockWidget(Qt::BottomDockWidgetArea, msgDock);
    resizeDocks({msgDock}, {110}, Qt::Vertical);
    resizeDocks({studyDock, renderDock, displayDock}, {220, 260, 300}, Qt::Vertical);

    // Status bar
    m_backend = new QLabel(tr("Renderer: —"), this);
    statusBar()->addPermanentWidget(m_backend);
    m_progress = new QProgressBar(this);
    m_progress->setRange(0, 1000);
    m_progress->setMinimumWidth(320);
    m_progress->setVisible(false);
    statusBar()->addPermanentWidget(m_progress);
    m_cancel = new QPushButton(tr("Cancel"), this);
    m_cancel->setVisible(false);
    statusBar()->addPermanentWidget(m_cancel);
    connect(m_cancel, &QPushButton::clicked, this, [this] { m_study->cancel(); });

    // Restore render settings.
    QSettings s;
    auto selectData = [](QComboBox* c, const QVariant& v) {
        const int i = c->findData(v);
        if (i >= 0) c->setCurrentIndex(i);
    };
    selectData(m_kernel, s.value("render/kernel", int(core::Kernel::KaiserBessel4)));
    selectData(m_size, s.value("render/size", 512));
    selectData(m_transform, s.value("render/transform", int(core::TransformKind::Fft)));
    selectData(m_oversampling, s.value("render/oversampling", 1.25));
    m_deapodize->setChecked(s.value("render/deapodize", true).toBool());
    selectData(m_values, s.value("render/values", int(core::ValueMapping::Mu)));
    m_invert->setChecked(s.value("display/invert", false).toBool());
    m_targetFps->setValue(s.value("render/targetFps", 30).toInt());
    m_clip->setChecked(s.value("render/clip", true).toBool());
    m_nonNegative->setChecked(s.value("render/nonNegative", true).toBool());
    m_pixelAperture->setChecked(s.value("render/pixelAperture", false).toBool());
    try {
        selectData(m_voxelModel, int(core::parseVoxelModel(s.value("render/voxelModel", "trilinear").toString().toStdString())));
    } catch (const core::SettingsError&) {
        selectData(m_voxelModel, int(core::VoxelModel::Trilinear)); // an unknown saved name: the default
    }
    m_energy->setValue(s.value("xray/energyKeV", 70.0).toDouble());
    m_exposure->setValue(s.value("xray/exposure", 1.0).toDouble());
    m_output->setCurrentIndex(s.value("xray/output", 0).toInt() == 1 ? 1 : 0);
    m_depthCue->setValue(s.value("xray/depthCue", 0).toInt());
    m_sharpen->setValue(s.value("xray/sharpen", 0.0).toDouble());
    m_sharpenRadius->setValue(s.value("xray/sharpenRadius", 1.0).toDouble());
    m_bandLimit->setValue(s.value("xray/bandLimit", 0.0).toDouble());
    m_muWater->setText(tr("%1 /mm").arg(core::waterAttenuationPerMm(m_energy->value()), 0, 'f', 4));
    for (auto* v : m_views) {
        v->setEffects(currentEffects());
        v->setTargetFps(m_targetFps->value());
    }
    m_viewSettings[0].kernel = core::Kernel(m_kernel->currentData().toInt());
    m_viewSettings[0].size = m_size->currentData().toInt();
    m_viewSettings[0].voxelModel = core::VoxelModel(m_voxelModel->currentData().toInt());
    if (!m_views.empty()) m_views[0]->setSettings(m_viewSettings[0]);
    SpectrumSettings ss;
    ss.mapping = core::ValueMapping(m_values->currentData().toInt());
    ss.transform = core::TransformKind(m_transform->currentData().toInt());
    ss.oversampling = m_oversampling->currentData().toDouble();
    ss.deapodizeFor = m_deapodize->isChecked() ? std::optional<core::Kernel>(m_viewSettings[0].kernel) : std::nullopt;
    m_study->setSpectrumSettings(ss);

    connect(m_kernel, &QComboBox::currentIndexChanged, this, [this] { applyRenderSettings(); });
    connect(m_size, &QComboBox::currentIndexChanged, this, [this] { applyRenderSettings(); });
    connect(m_compareSlot, &QComboBox::currentIndexChanged, this, [this](int slot) {
        if (slot <= 0 || slot > int(m_views.size())) return;
        const ViewSettings vs = m_views[slot - 1]->settings();
        const QSignalBlocker b1(m_kernel), b2(m_size), b3(m_voxelModel);
        m_kernel->setCurrentIndex(m_kernel->findData(int(vs.kernel)));
        m_size->setCurrentIndex(m_size->findData(vs.size));
        m_voxelModel->setCurrentIndex(m_voxelModel->findData(int(vs.voxelModel)));
    });
    connect(m_transform, &QComboBox::currentIndexChanged, this, [this] { applySpectrumSettings(); });
    connect(m_oversampling, &QComboBox::currentIndexChanged, this, [this] { applySpectrumSettings(); });
    connect(m_values, &QComboBox::currentIndexChanged, this, [this] {
        if (m_output->currentData().toInt() == 1 &&
            core::ValueMapping(m_values->currentData().toInt()) == core::ValueMapping::Raw) {
            message(tr("Raw values have no transmission: the output is line integrals again."));
            const QSignalBlocker b(m_output);
            m_output->setCurrentIndex(0);
            applyOutput(true);
        }
        m_rewindow = true; // new values, new range: window again when the spectrum is ready
        applySpectrumSettings();
    });
    connect(m_deapodize, &QCheckBox::toggled, this, [this] { applySpectrumSettings(); });
    connect(m_width, &QDoubleSpinBox::valueChanged, this, [this] { applyWindowFromPanel(); });
    connect(m_level, &QDoubleSpinBox::valueChanged, this, [this] { applyWindowFromPanel(); });
    connect(m_invert, &QCheckBox::toggled, this, [this] { applyWindowFromPanel(); });
    connect(autoBtn, &QPushButton::clicked, this, [this] { applyPreset(m_preset->itemText(0)); });
    connect(m_targetFps, &QSpinBox::valueChanged, this, [this](int fps) {
        for (auto* v : m_views) v->setTargetFps(m_difference ? 0 : fps);
        QSettings().setValue("render/targetFps", fps);
    });
    connect(m_output, &QComboBox::currentIndexChanged, this, [this] { applyOutput(true); });
    connect(m_energy, &QDoubleSpinBox::valueChanged, this, [this] { applyOutput(false); });
    connect(m_exposure, &QDoubleSpinBox::valueChanged, this, [this] { applyOutput(false); });
    for (auto* sb : {m_sharpen, m_sharpenRadius, m_bandLimit})
        connect(sb, &QDoubleSpinBox::valueChanged, this, [this] { applyEffects(); });
    connect(m_depthCue, &QSpinBox::valueChanged, this, [this] { applyEffects(); });
    connect(m_clip, &QCheckBox::toggled, this, [this] { applyEffects(); });
    connect(m_nonNegative, &QCheckBox::toggled, this, [this] { applyEffects(); });
    connect(m_pixelAperture, &QCheckBox::toggled, this, [this] { applyEffects(); });
    connect(m_voxelModel, &QComboBox::currentIndexChanged, this, [this] { applyVoxelModel(); });
    m_energy->setEnabled(m_output->currentIndex() == 1);
    m_exposure->setEnabled(m_output->currentIndex() == 1);
    if (m_output->currentIndex() == 1) applyOutput(true);
    connect(m_preset, &QComboBox::textActivated, this, [this](const QString& p) { applyPreset(p); });
}

void MainWindow::buildMenus() {
    QMenu* file = menuBar()->addMenu(tr("&File"));
    QAction* openFolder = file->addAction(tr("Open DICOM &folder…"), this, &MainWindow::openFolderDialog);
    openFolder->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_D));
    QAction* openFile = file->addAction(tr("&Open volume file…"), this, &MainWindow::openFileDialog);
    openFile->setShortcut(QKeySequence::Open);
    file->addAction(tr("Open built-in &phantom"), this, [this] { openStudy(StudySource::phantom(128)); });
    m_recentMenu = file->addMenu(tr("&Recent studies"));
    file->addSeparator();
    QAction* shot = file->addAction(tr("Export &screenshot (PNG)…"), this, &MainWindow::exportScreenshotDialog);
    shot->setShortcut(QKeySequence::Save);
    file->addAction(tr("Export &projection (16-bit PNG, .npy, .pfm)…"), this, &MainWindow::exportProjectionDialog);
    file->addAction(tr("Export rotation s&weep…"), this, &MainWindow::exportSweepDialog);
    QAction* copy = file->addAction(tr("&Copy view to clipboard"), this, &MainWindow::copyToClipboard);
    copy->setShortcut(QKeySequence::Copy);
    file->addSeparator();
    QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
    quit->setShortcut(QKeySequence::Quit);

    QMenu* view = menuBar()->addMenu(tr("&View"));
    QToolBar* tb = addToolBar(tr("Main"));
    tb->setObjectName("toolbar.main");
    tb->addAction(openFolder);
    tb->addAction(openFile);
    tb->addSeparator();
    const std::pair<core::PatientView, Qt::Key> views[] = {
        {core::PatientView::AP, Qt::Key_1},   {core::PatientView::PA, Qt::Key_2},
        {core::PatientView::Left, Qt::Key_3}, {core::PatientView::Right, Qt::Key_4},
        {core::PatientView::Head, Qt::Key_5}, {core::PatientView::Feet, Qt::Key_6}};
    for (const auto& [pv, key] : views) {
        QAction* a = view->addAction(QString::fromUtf8(core::patientViewName(pv)), this, [this, pv] { showPatientView(pv); });
        a->setShortcut(QKeySequence(key));
        a->setToolTip(tr("Patient view %1 (%2)").arg(QString::fromUtf8(core::patientViewName(pv))).arg(QKeySequence(key).toString()));
        tb->addAction(a);
    }
    QAction* reset = view->addAction(tr("&Reset view"), this, [this] {
        showPatientView(core::PatientView::AP);
        for (auto* v : m_views) v->resetPanZoom();
    });
    reset->setShortcut(QKeySequence(Qt::Key_R));
    tb->addAction(reset);
    view->addSeparator();
    tb->addSeparator();
    for (int n : {1, 2, 4}) {
        QAction* a = view->addAction(n == 1 ? tr("Single view") : tr("Compare %1 views").arg(n), this,
                                     [this, n] { setCompareCount(n); });
        tb->addAction(a);
    }
    QAction* diff = view->addAction(tr("&Difference to view 1"));
    diff->setCheckable(true);
    connect(diff, &QAction::toggled, this, [this](bool on) { setDifferenceMode(on); });
    view->addSeparator();
    m_overlayAction = view->addAction(tr("Performance &overlay"));
    m_overlayAction->setCheckable(true);
    m_overlayAction->setShortcut(QKeySequence(Qt::Key_F));
    m_overlayAction->setChecked(QSettings().value("view/overlay", true).toBool());
    connect(m_overlayAction, &QAction::toggled, this, [this](bool on) {
        for (auto* v : m_views) v->setOverlayVisible(on);
    });
    for (auto* v : m_views) v->setOverlayVisible(m_overlayAction->isChecked());
    QAction* acc = view->addAction(tr("&Accuracy against ray casting"), this, &MainWindow::measureAccuracy);
    acc->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_A));
    view->addAction(tr("Reset &zoom"), this, [this] {
        for (auto* v : m_views) v->resetPanZoom();
    });

    QMenu* help = menuBar()->addMenu(tr("&Help"));
    help->addAction(tr("&About"), this, [this] {
        QMessageBox::about(this, tr("About %1").arg(QString::fromUtf8(applicationName())),
                           tr("<b>%1 %2</b><p>X-ray-like projections by Fourier volume rendering "
                              "(Viola, Kanitsar, Gröller). Parallel projection, no occlusion: every "
                              "pixel is a line integral through the whole volume.</p>")
                               .arg(QString::fromUtf8(applicationName()), QString::fromUtf8(applicationVersion())));
    });
}

void MainWindow::openStudy(const StudySource& source) {
    message(tr("Opening %1…").arg(source.kind == StudySource::Kind::Phantom ? source.displayName() : source.path));
    if (source.kind != StudySource::Kind::Phantom) addRecent(source.path);
    m_study->open(source);
}

QString MainWindow::viewTitle(int index, const ViewSettings& s) const {
    // Short enough to clear the orientation label above the image; the overlay's first line
    // names the voxel model.
    return tr("View %1: %2 %3×%3").arg(index + 1).arg(QString::fromUtf8(core::kernelName(s.kernel))).arg(s.size);
}

void MainWindow::applyVoxelModel() {
    // Only the voxel model of the views "Applies to" names: their kernels and sizes stay (in
    // compare mode each view keeps its own). Same spectrum: nothing is preprocessed again.
    const core::VoxelModel model = core::VoxelModel(m_voxelModel->currentData().toInt());
    const int slot = m_compareSlot->currentIndex();
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        ViewSettings s = m_views[i]->settings();
        s.voxelModel = model;
        m_viewSettings[i].voxelModel = model;
        m_views[i]->setSettings(s);
    }
    saveVoxelModelSetting();
}

void MainWindow::saveVoxelModelSetting() {
    // The startup setting follows view 1.
    if (!m_views.empty())
        QSettings().setValue("render/voxelModel", QString::fromUtf8(core::voxelModelName(m_views[0]->settings().voxelModel)));
}

void MainWindow::applyRenderSettings() {
    ViewSettings s;
    s.kernel = core::Kernel(m_kernel->currentData().toInt());
    s.size = m_size->currentData().toInt();
    s.voxelModel = core::VoxelModel(m_voxelModel->currentData().toInt());
    const int slot = m_compareSlot->currentIndex();
    const bool respectrum = m_deapodize->isChecked() && m_study->spectrum() &&
                            m_study->spectrum()->deapodizedFor && *m_study->spectrum()->deapodizedFor != s.kernel;
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        m_viewSettings[i] = s;
        // A spectrum deapodized for another kernel cannot render this one: the views switch when
        // the new spectrum is ready (onSpectrumReady).
        if (!respectrum) m_views[i]->setSettings(s);
        if (m_compareCount > 1) m_views[i]->setTitle(viewTitle(i, s));
    }
    QSettings st;
    st.setValue("render/kernel", int(s.kernel));
    st.setValue("render/size", s.size);
    saveVoxelModelSetting();
    if (m_deapodize->isChecked()) applySpectrumSettings();
}

void MainWindow::applySpectrumSettings() {
    SpectrumSettings s;
    s.mapping = core::ValueMapping(m_values->currentData().toInt());
    s.transform = core::TransformKind(m_transform->currentData().toInt());
    s.oversampling = m_oversampling->currentData().toDouble();
    s.deapodizeFor = m_deapodize->isChecked() ? std::optional<core::Kernel>(m_viewSettings[0].kernel) : std::nullopt;
    QSettings st;
    st.setValue("render/deapodize", m_deapodize->isChecked());
    st.setValue("render/transform", int(s.transform));
    st.setValue("render/oversampling", s.oversampling);
    st.setValue("render/values", int(s.mapping));
    if (m_study->volume()) m_memory->setText(tr("%1 MiB").arg(m_study->estimatedSpectrumMiB(s), 0, 'f', 1));
    if (m_study->volume() && !(s == m_study->spectrumSettings()))
        message(tr("Preprocessing again (%1, oversampling %2, %3)…")
                    .arg(QString::fromUtf8(core::transformName(s.transform)))
                    .arg(s.oversampling)
                    .arg(QString::fromUtf8(core::valueMappingName(s.mapping)))
                + (s.deapodizeFor ? tr(", deapodized for %1").arg(QString::fromUtf8(core::kernelName(*s.deapodizeFor)))
                                  : QString()));
    m_study->setSpectrumSettings(s);
}

void MainWindow::applyWindowFromPanel() {
    if (m_syncing || m_views.empty()) return;
    core::DisplayWindow w;
    w.low = m_level->value() - m_width->value() / 2;
    w.high = m_level->value() + m_width->value() / 2;
    w.invert = m_invert->isChecked();
    w.transmission = currentTransmission();
    m_syncing = true;
    for (std::size_t i = 0; i < m_views.size(); ++i)
        if (i == 0 || !m_difference) m_views[i]->setWindow(w);
    m_syncing = false;
    QSettings().setValue("display/invert", w.invert);
}

void MainWindow::syncWindowToPanel(const core::DisplayWindow& w) {
    const QSignalBlocker b1(m_width), b2(m_level), b3(m_invert);
    m_width->setValue(w.high - w.low);
    m_level->setValue((w.high + w.low) / 2);
    m_invert->setChecked(w.invert);
}

void MainWindow::applyPreset(const QString& name) {
    if (m_views.empty()) return;
    auto p = m_views[0]->projection();
    if (!p) return;
    const core::Transmission t = currentTransmission();
    if (t.active()) core::applyLogExposure(p->pixels, t); // the window applies to the log exposure
    std::vector<float> v = p->pixels;
    std::sort(v.begin(), v.end());
    auto q = [&](double f) { return double(v[std::size_t(f * (v.size() - 1))]); };
    core::DisplayWindow w;
    const int idx = m_preset->findText(name);
    switch (idx) {
    case 1: w = {v.front(), v.back(), false}; break;
    case 2: w = {q(0.005) + 0.55 * (q(0.995) - q(0.005)), q(0.995), false}; break;
    case 3: w = {q(0.005) + 0.10 * (q(0.995) - q(0.005)), q(0.005) + 0.70 * (q(0.995) - q(0.005)), false}; break;
    default: w = core::autoWindow(p->pixels); break;
    }
    if (!(w.high > w.low)) w.high = w.low + 1.0;
    w.invert = m_invert->isChecked();
    syncWindowToPanel(w);
    applyWindowFromPanel();
}

core::Transmission MainWindow::currentTransmission() const {
    if (!m_output || m_output->currentData().toInt() != 1) return {};
    return {core::waterAttenuationPerMm(m_energy->value()), m_exposure->value()};
}

FrameEffects MainWindow::currentEffects() const {
    FrameEffects e;
    if (!m_depthCue) return e;
    e.depthCue = m_depthCue->value() / 100.0;
    e.filter.sharpenAmount = m_sharpen->value();
    e.filter.sharpenSigmaMm = m_sharpenRadius->value();
    e.filter.bandLimitLpMm = m_bandLimit->value();
    e.clip = m_clip->isChecked();
    e.nonNegative = m_nonNegative->isChecked();
    e.pixelAperture = m_pixelAperture->isChecked();
    return e;
}

void MainWindow::applyEffects() {
    const FrameEffects e = currentEffects();
    for (auto* v : m_views) v->setEffects(e);
    QSettings st;
    st.setValue("xray/depthCue", m_depthCue->value());
    st.setValue("xray/sharpen", e.filter.sharpenAmount);
    st.setValue("xray/sharpenRadius", e.filter.sharpenSigmaMm);
    st.setValue("xray/bandLimit", e.filter.bandLimitLpMm);
    st.setValue("render/clip", e.clip);
    st.setValue("render/nonNegative", e.nonNegative);
    st.setValue("render/pixelAperture", e.pixelAperture);
    if (e.depthCue > 0 && std::any_of(m_views.begin(), m_views.end(), [](ProjectionView* v) {
            return v->settings().kernel == core::Kernel::Nearest;
        }))
        message(tr("Depth cueing needs the derivative of the interpolation kernel: views with nearest neighbour "
                   "are not rendered until you choose linear or better."),
                true);
}

void MainWindow::applyOutput(bool resetWindow) {
    const bool transmission = m_output->currentData().toInt() == 1;
    m_muWater->setText(tr("%1 /mm").arg(core::waterAttenuationPerMm(m_energy->value()), 0, 'f', 4));
    m_energy->setEnabled(transmission);
    m_exposure->setEnabled(transmission);
    QSettings st;
    st.setValue("xray/energyKeV", m_energy->value());
    st.setValue("xray/exposure", m_exposure->value());
    st.setValue("xray/output", transmission ? 1 : 0);
    if (transmission && core::ValueMapping(m_values->currentData().toInt()) == core::ValueMapping::Raw) {
        // Beer-Lambert needs attenuation: switch the values to mu (preprocesses again).
        const auto vol = m_study->volume();
        if (vol && vol->units != core::ValueUnits::HounsfieldUnits) {
            message(tr("Transmitted intensity needs attenuation values; this study's values are not Hounsfield "
                       "units (%1), so the output stays line integrals.")
                        .arg(QString::fromUtf8(core::unitsName(vol->units))),
                    true);
            const QSignalBlocker b(m_output);
            m_output->setCurrentIndex(0);
            return applyOutput(true);
        }
        message(tr("Transmitted intensity needs attenuation values: switching the values to μ."));
        m_values->setCurrentIndex(m_values->findData(int(core::ValueMapping::Mu))); // applySpectrumSettings
        m_rewindow = true; // the window follows the new spectrum's image (onSpectrumReady)
    }
    if (resetWindow) {
        const QSignalBlocker b(m_invert);
        m_invert->setChecked(transmission); // film look (bone white) for transmission
        // The window from the image (log exposure for transmission); before any image, the
        // first three decades of exposure.
        syncWindowToPanel({-3.0, 0.0, transmission, currentTransmission()});
        applyWindowFromPanel();
        applyPreset(m_preset->itemText(0));
    } else {
        applyWindowFromPanel();
    }
}

void MainWindow::onStudyLoaded(const QString& name) {
    setWindowTitle(QStringLiteral("%1 — %2").arg(QString::fromUtf8(applicationName()), name));
    message(tr("Opened %1").arg(name));
    for (auto* v : m_views) {
        v->setStudy(m_study->volume(), m_study->spectrum());
        v->setViewFrame(core::patientViewFrame(*m_study->volume(), core::PatientView::AP));
    }
    updateStudyInfo();
}

void MainWindow::onSpectrumReady() {
    // A newer preprocessing started after this one (the user changed settings meanwhile): the
    // views show this spectrum, but the panel keeps the newer settings and the progress bar.
    const bool newer = m_study->busy();
    if (!newer) {
        m_progress->setVisible(false);
        m_cancel->setVisible(false);
    }
    if (!newer) { // the controller may have adjusted the settings (e.g. raw values for non-HU data)
        const SpectrumSettings& s = m_study->spectrumSettings();
        const QSignalBlocker b1(m_values), b2(m_transform), b3(m_oversampling);
        m_values->setCurrentIndex(m_values->findData(int(s.mapping)));
        m_transform->setCurrentIndex(m_transform->findData(int(s.transform)));
        m_oversampling->setCurrentIndex(m_oversampling->findData(s.oversampling));
    }
    if (!newer && m_output->currentData().toInt() == 1 &&
        m_study->spectrumSettings().mapping == core::ValueMapping::Raw) {
        message(tr("This study integrates raw values (not Hounsfield units): no transmitted intensity, the output "
                   "is line integrals."),
                true);
        const QSignalBlocker b(m_output);
        m_output->setCurrentIndex(0);
        applyOutput(true);
    }
    for (std::size_t i = 0; i < m_views.size(); ++i) m_views[i]->setSettings(m_viewSettings[i]);
    for (auto* v : m_views) v->setStudy(m_study->volume(), m_study->spectrum());
    if (m_rewindow && !newer) {
        m_rewindow = false;
        applyPreset(m_preset->itemText(0));
    }
    updateStudyInfo();
}

void MainWindow::updateStudyInfo() {
    const auto vol = m_study->volume();
    if (!vol) {
        m_studyInfo->setText(tr("No study"));
        return;
    }
    const auto spec = m_study->spectrum();
    const auto [lo, hi] = vol->valueRange();
    QString html = QStringLiteral("<b>%1</b><br>").arg(m_study->source().displayName().toHtmlEscaped());
    html += tr("Dimensions: %1 × %2 × %3<br>").arg(vol->dims[0]).arg(vol->dims[1]).arg(vol->dims[2]);
    html += tr("Spacing: %1 × %2 × %3 mm<br>").arg(vol->spacing[0], 0, 'g', 4).arg(vol->spacing[1], 0, 'g', 4).arg(vol->spacing[2], 0, 'g', 4);
    html += tr("Values: %1 … %2 %3<br>")
                .arg(lo, 0, 'g', 5)
                .arg(hi, 0, 'g', 5)
                .arg(vol->units == core::ValueUnits::Unknown ? tr("(units not stated)")
                                                             : QString::fromUtf8(core::unitsName(vol->units)));
    if (spec)
        html += tr("Spectrum: %1 × %2 × %3 padded, %4 MiB, %5<br>")
                    .arg(spec->padded[0]).arg(spec->padded[1]).arg(spec->padded[2])
                    .arg(double(spec->bytes()) / (1 << 20), 0, 'f', 1)
                    .arg(QString::fromUtf8(core::transformName(spec->kind)).toUpper());
    html += tr("<small>Parallel projection without occlusion: every pixel is a line integral.</small>");
    for (const auto& w : m_study->warnings()) html += QStringLiteral("<br><font color='#d04020'>⚠ %1</font>").arg(w.toHtmlEscaped());
    m_studyInfo->setText(html);
    if (spec) m_memory->setText(tr("%1 MiB").arg(double(spec->bytes()) / (1 << 20), 0, 'f', 1));
}

void MainWindow::message(const QString& text, bool error) {
    const QString line = QStringLiteral("%1  %2").arg(QTime::currentTime().toString("HH:mm:ss"), text);
    m_messages->appendPlainText(line);
    statusBar()->showMessage(text, error ? 10000 : 4000);
}

void MainWindow::showPatientView(core::PatientView pv) {
    if (!m_study->volume() || m_views.empty()) return;
    const auto f = core::patientViewFrame(*m_study->volume(), pv);
    for (auto* v : m_views) v->setViewFrame(f);
}

void MainWindow::addRecent(const QString& path) {
    QSettings s;
    QStringList recent = s.value("recent").toStringList();
    recent.removeAll(path);
    recent.prepend(path);
    while (recent.size() > kMaxRecent) recent.removeLast();
    s.setValue("recent", recent);
    s.setValue("lastFolder", QFileInfo(path).isDir() ? path : QFileInfo(path).absolutePath());
    rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
    if (!m_recentMenu) return;
    m_recentMenu->clear();
    const QStringList recent = QSettings().value("recent").toStringList();
    for (const QString& p : recent)
        m_recentMenu->addAction(p, this, [this, p] { openStudy(StudySource::fromPath(p)); });
    m_recentMenu->setEnabled(!recent.isEmpty());
}

void MainWindow::openFileDialog() {
    const QString path = QFileDialog::getOpenFileName(this, tr("Open volume file"), QSettings().value("lastFolder").toString(),
                                                      tr("Volumes (*.mhd *.mha *.nii *.nii.gz);;All files (*)"));
    if (!path.isEmpty()) openStudy(StudySource::fromPath(path));
}

void MainWindow::openFolderDialog() {
    const QString path = QFileDialog::getExistingDirectory(this, tr("Open DICOM folder"), QSettings().value("lastFolder").toString());
    if (!path.isEmpty()) openStudy(StudySource::fromPath(path));
}

bool MainWindow::exportScreenshot(const QString& path) {
    if (m_views.empty()) return false;
    const QImage img = m_compareCount == 1 ? m_views[0]->screenshot() : m_viewHost->grab().toImage();
    QSaveFile f(path);
    if (!f.open(QIODevice::WriteOnly) || !img.save(&f, "PNG") || !f.commit()) {
        message(tr("Could not write %1: %2").arg(path, f.errorString()), true);
        return false;
    }
    message(tr("Saved screenshot %1").arg(path));
    return true;
}

bool MainWindow::exportProjection(const QString& path) {
    if (m_views.empty()) return false;
    const auto p = m_views[0]->projection();
    if (!p) {
        message(tr("Nothing to export yet"), true);
        return false;
    }
    // Float exports hold what the display shows before the window: the transmitted intensity in
    // Beer-Lambert mode, else the line integrals. The PNG goes through the display window itself.
    const core::Transmission t = currentTransmission();
    try {
        const QString ext = QFileInfo(path).suffix().toLower();
        const std::string out = path.toStdString();
        std::vector<float> values = p->pixels;
        if (t.active() && ext != "png") core::applyTransmission(values, t);
        if (ext == "npy") core::writeNpy(out, values.data(), p->size, p->size);
        else if (ext == "pfm") core::writePfm(out, values.data(), p->size, p->size);
        else if (ext == "png") core::writePng(out, p->pixels.data(), p->size, p->size, m_views[0]->window(), 16);
        else throw core::WriteError(out + ": unknown format (expected .npy, .pfm or .png)");
    } catch (const std::exception& e) {
        message(tr("Could not export: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    message(tr("Exported projection %1 (%2 × %2, pixel %3 mm, %4)")
                .arg(path)
                .arg(p->size)
                .arg(p->pixelSize, 0, 'g', 4)
                .arg(t.active() ? tr("transmitted intensity, μ_water %1/mm, exposure %2").arg(t.muWaterPerMm, 0, 'f', 4).arg(t.exposure)
                                : tr("line integrals")));
    return true;
}

bool MainWindow::exportSweep(const QString& folder, int frames, const core::Vec3& axis) {
    if (m_views.empty() || !m_study->spectrum() || frames < 1) return false;
    if (!QDir().mkpath(folder)) {
        message(tr("Could not create %1").arg(folder), true);
        return false;
    }
    ProjectionView* v = m_views[0];
    const core::ViewFrame start = v->viewFrame();
    QProgressDialog progress(tr("Exporting rotation sweep…"), tr("Cancel"), 0, frames, this);
    progress.setWindowModality(Qt::WindowModal);
    std::vector<float> stack;
    int M = 0;
    bool ok = true;
    for (int i = 0; i < frames; ++i) {
        progress.setValue(i);
        if (progress.wasCanceled()) {
            ok = false;
            break;
        }
        v->setViewFrame(start.rotated(axis, 2.0 * std::numbers::pi * i / frames));
        const auto p = v->projection();
        if (!p) {
            ok = false;
            break;
        }
        M = p->size;
        if (const core::Transmission t = currentTransmission(); t.active()) {
            std::vector<float> intensity = p->pixels;
            core::applyTransmission(intensity, t);
            stack.insert(stack.end(), intensity.begin(), intensity.end());
        } else {
            stack.insert(stack.end(), p->pixels.begin(), p->pixels.end());
        }
        try {
            core::writePng(QDir(folder).filePath(QStringLiteral("frame_%1.png").arg(i, 4, 10, QChar('0'))).toStdString(),
                           p->pixels.data(), M, M, v->window(), 8);
        } catch (const std::exception& e) {
            message(tr("Sweep export failed: %1").arg(QString::fromUtf8(e.what())), true);
            ok = false;
            break;
        }
    }
    progress.setValue(frames);
    v->setViewFrame(start);
    if (ok) {
        try {
            core::writeNpy(QDir(folder).filePath("sweep.npy").toStdString(), stack.data(), M, M, frames);
        } catch (const std::exception& e) {
            message(tr("Sweep export failed: %1").arg(QString::fromUtf8(e.what())), true);
            return false;
        }
        message(tr("Exported %1 frames to %2 (PNG frames and sweep.npy)").arg(frames).arg(folder));
    } else {
        message(tr("Sweep export stopped"), true);
    }
    return ok;
}

void MainWindow::exportScreenshotDialog() {
    const QString path = QFileDialog::getSaveFileName(this, tr("Export screenshot"), QSettings().value("lastFolder").toString() + "/view.png",
                                                      tr("PNG image (*.png)"));
    if (!path.isEmpty()) exportScreenshot(path);
}

void MainWindow::exportProjectionDialog() {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Export projection"), QSettings().value("lastFolder").toString() + "/projection.npy",
        tr("Float line integrals (*.npy);;16-bit PNG, current window (*.png);;PFM float (*.pfm)"));
    if (!path.isEmpty()) exportProjection(path);
}

void MainWindow::exportSweepDialog() {
    bool ok = false;
    const int n = QInputDialog::getInt(this, tr("Rotation sweep"), tr("Frames around the patient's head-feet axis:"), 36, 1,
                                       3600, 1, &ok);
    if (!ok) return;
    const QString folder = QFileDialog::getExistingDirectory(this, tr("Folder for the sweep"), QSettings().value("lastFolder").toString());
    if (folder.isEmpty() || !m_study->volume()) return;
    // Head-feet axis of the patient in the volume's index frame.
    const auto& d = m_study->volume()->direction;
    exportSweep(folder, n, {d[0][2], d[1][2], d[2][2]});
}

void MainWindow::copyToClipboard() {
    if (m_views.empty()) return;
    QGuiApplication::clipboard()->setImage(m_compareCount == 1 ? m_views[0]->screenshot() : m_viewHost->grab().toImage());
    message(tr("Copied the view to the clipboard"));
}

void MainWindow::closeEvent(QCloseEvent* e) {
    m_study->cancel();
    QSettings s;
    s.setValue("window/geometry", saveGeometry());
    s.setValue("window/state", saveState());
    s.setValue("view/overlay", m_overlayAction->isChecked());
    QMainWindow::closeEvent(e);
}

void MainWindow::dragEnterEvent(QDragEnterEvent* e) {
    if (e->mimeData()->hasUrls()) e->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* e) {
    for (const QUrl& u : e->mimeData()->urls())
        if (u.isLocalFile()) {
            openStudy(StudySource::fromPath(u.toLocalFile()));
            return;
        }
}

void MainWindow::keyPressEvent(QKeyEvent* e) { QMainWindow::keyPressEvent(e); }

} // namespace fvr::ui
