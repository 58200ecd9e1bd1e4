// The polychromatic output's material spectra, prepared in the background by the
// MaterialsController: one spectrum per material and gridding correction, of the volume asked
// for; another volume cancels the old volume's job; an error is said, not swallowed.
#include <QSignalSpy>
#include <QTest>

#include <memory>

#include <gtest/gtest.h>

#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/ui/materials_controller.h>

#include "ui/ui_support.h"

using namespace fvr;
using ui::MaterialsController;

namespace {

constexpr int kGuardMs = 120000; // against a hang only

std::shared_ptr<const core::Volume> phantom(int n) {
    return std::make_shared<const core::Volume>(core::makeSheppLoganVolume(n));
}

core::PreprocessOptions options() {
    core::PreprocessOptions o;
    o.oversampling = 1.25;
    return o;
}

} // namespace

TEST(MaterialsController, PreparesEachMaterialPerGriddingCorrectionOfTheVolume) {
    test::app();
    MaterialsController c;
    const auto vol = phantom(32);
    EXPECT_TRUE(c.setVolume(vol));
    EXPECT_FALSE(c.setVolume(vol)); // the same volume keeps its spectra
    QSignalSpy ready(&c, &MaterialsController::ready);
    const int kb = int(core::Kernel::KaiserBessel4);
    c.prepare({-1, kb}, options());
    EXPECT_TRUE(c.busy());
    ASSERT_TRUE(ready.wait(kGuardMs));
    EXPECT_FALSE(c.busy());
    const std::size_t materials = core::MaterialMapping{}.materials.size();
    ASSERT_EQ(c.spectra().size(), 2u);
    double bytes = 0;
    for (const auto& [key, spectra] : c.spectra()) {
        ASSERT_EQ(spectra.size(), materials);
        for (const auto& s : spectra) {
            EXPECT_EQ(s->volumeDims, vol->dims);
            if (key < 0)
                EXPECT_FALSE(s->deapodizedFor);
            else
                EXPECT_EQ(s->deapodizedFor, core::Kernel(key));
            bytes += double(s->bytes());
        }
    }
    EXPECT_EQ(c.spectrumCount(), int(2 * materials));
    EXPECT_DOUBLE_EQ(c.spectraMiB(), bytes / (1 << 20));
    EXPECT_TRUE(c.has(kb));
    EXPECT_FALSE(c.has(int(core::Kernel::Sinc4)));
}

TEST(MaterialsController, AnotherVolumeDiscardsTheOldVolumesJob) {
    test::app();
    MaterialsController c;
    QSignalSpy ready(&c, &MaterialsController::ready);
    QSignalSpy discarded(&c, &MaterialsController::discarded);
    c.setVolume(phantom(96));
    c.prepare({-1}, options());
    const auto other = phantom(24);
    EXPECT_TRUE(c.setVolume(other)); // cancels the job
    EXPECT_TRUE(c.spectra().empty());
    EXPECT_TRUE(c.busy()); // until its end is handled
    ASSERT_TRUE(discarded.wait(kGuardMs));
    EXPECT_EQ(ready.count(), 0);
    EXPECT_TRUE(c.spectra().empty());
    c.prepare({-1}, options());
    ASSERT_TRUE(ready.wait(kGuardMs));
    ASSERT_EQ(c.spectra().count(-1), 1u);
    for (const auto& s : c.spectra().at(-1)) EXPECT_EQ(s->volumeDims, other->dims);
}

TEST(MaterialsController, AnErrorIsSaid) {
    test::app();
    MaterialsController c;
    QSignalSpy failed(&c, &MaterialsController::failed);
    c.setVolume(phantom(16));
    core::PreprocessOptions bad;
    bad.oversampling = 7.0; // outside [1, 2]
    c.prepare({-1}, bad);
    ASSERT_TRUE(failed.wait(kGuardMs));
    const QString error = failed.front().front().toString();
    EXPECT_TRUE(error.contains(QStringLiteral("oversampling")) &&
                error.contains(QStringLiteral("7")))
        << error.toStdString();
    EXPECT_FALSE(c.busy());
    EXPECT_TRUE(c.spectra().empty());
}
