// A prior beside the current study: view 2 shows it as the same view of the patient, whatever
// its storage order, turned with view 1.
#include <QFile>

#include <cmath>
#include <fstream>

#include <fvr/core/xray/phantom.h>
#include <fvr/ui/settings_model.h>

#include "ui_support.h"

namespace fvr::test {
namespace {

/** `v` written as a MetaImage stored mirrored: index x runs to the patient's right, the
 *  TransformMatrix says so (determinant −1). The same patient, another storage. */
std::string writeMirrored(const core::Volume& v, const std::string& name) {
    const auto path = tmpDir() / name;
    std::ofstream out(path, std::ios::binary);
    const long nx = v.dims[0], ny = v.dims[1], nz = v.dims[2];
    out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        << "DimSize = " << nx << ' ' << ny << ' ' << nz << "\nElementSpacing = " << v.spacing.x
        << ' ' << v.spacing.y << ' ' << v.spacing.z
        << "\nTransformMatrix = -1 0 0 0 1 0 0 0 1\nElementType = MET_FLOAT\n"
        << "ElementDataFile = LOCAL\n";
    std::vector<float> row(static_cast<std::size_t>(nx));
    for (long z = 0; z < nz; ++z)
        for (long y = 0; y < ny; ++y) {
            for (long x = 0; x < nx; ++x)
                row[std::size_t(x)] = v.voxels[std::size_t((z * ny + y) * nx + (nx - 1 - x))];
            out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size() * 4));
        }
    return path.string();
}

/** The largest difference of two projections, relative to the first one's range. */
double relativeMaxDiff(const core::ProjectionImage& a, const core::ProjectionImage& b) {
    EXPECT_EQ(a.pixels.size(), b.pixels.size());
    if (a.pixels.size() != b.pixels.size()) return 1e9;
    const auto [lo, hi] = std::minmax_element(a.pixels.begin(), a.pixels.end());
    double m = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        m = std::max(m, double(std::abs(a.pixels[i] - b.pixels[i])));
    return m / std::max(1e-9, double(*hi - *lo));
}

TEST_F(Workstation, APriorStoredMirroredShowsTheSamePatientViewTurnedWithTheCurrent) {
    // Raw values: the MetaImage states no units, so both studies integrate the stored values.
    ui::RenderingPanel::Values r = window->settings().rendering();
    r.mapping = core::ValueMapping::Raw;
    r.size = 128;
    window->settings().setRendering(r);
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(48)));
    const std::string prior = writeMirrored(core::makeChestPhantomVolume(48), "prior-mirrored.mha");
    QSignalSpy ready(window.get(), &MainWindow::priorReady);
    window->openPrior(StudySource::fromPath(QString::fromStdString(prior)));
    ASSERT_TRUE(ready.wait(60000)) << window->messages()->toPlainText().toStdString();
    ASSERT_TRUE(window->hasPrior());
    ASSERT_EQ(window->views().size(), 2u);
    auto* current = window->views()[0];
    auto* shown = window->views()[1];
    EXPECT_EQ(shown->volume(), window->prior()->volume());
    EXPECT_TRUE(shown->overlayText().startsWith("Prior:")) << shown->overlayText().toStdString();
    for (const auto& [h, v] : {std::pair{0.0, 0.0}, {30.0, 10.0}, {95.0, -40.0}}) {
        window->rotateViews(h, v);
        QTest::qWait(20);
        const auto a = current->projection();
        const auto b = shown->projection();
        ASSERT_TRUE(a && b);
        // The same anatomy the same way up: the same image.
        EXPECT_LT(relativeMaxDiff(*a, *b), 2e-3) << "after turning " << h << ", " << v;
        EXPECT_EQ(current->orientationLabels(), shown->orientationLabels());
        // Not by copying the frame: in the mirrored volume's index frame it differs.
        EXPECT_NEAR(shown->viewFrame().d.x, -current->viewFrame().d.x, 1e-12);
    }
    // Two studies on their own grids do not subtract: Difference is refused, by reason.
    window->setDifferenceMode(true);
    EXPECT_FALSE(window->currentState().difference);
    EXPECT_TRUE(window->messages()->toPlainText().contains("shows a prior"));
    window->closePrior();
    EXPECT_FALSE(window->hasPrior());
    EXPECT_EQ(window->views()[1]->volume(), window->study().volume());
}

} // namespace
} // namespace fvr::test
