// The workstation's render settings come from core::RenderSettings: the panels' defaults are its
// defaults, the settings are saved by name and the enum numbers that earlier versions saved
// still load. (That a default render is fvr-render's default image: ScriptedRun.)
#include <QComboBox>
#include <QSettings>
#include <QTemporaryDir>

#include <gtest/gtest.h>

#include <fvr/core/render/render_settings.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>

#include "ui/ui_support.h"

using namespace fvr;

namespace {

/** A settings file of its own (an INI file in a temporary folder). */
struct ScratchSettings {
    QTemporaryDir dir;
    QSettings settings{dir.filePath("s.ini"), QSettings::IniFormat};
};

TEST(RenderSettings, ThePanelsDefaultsAreCoresDefaults) {
    test::app();
    const ui::SettingsModel model;
    EXPECT_EQ(model.renderSettings(), core::RenderSettings{});
    // The pieces the views take: view 1's kernel, size and voxel model, the spectrum.
    const ui::ViewSettings view = model.viewSettings();
    EXPECT_EQ(view.kernel, core::RenderSettings{}.kernel);
    EXPECT_EQ(view.size, core::RenderSettings{}.size);
    EXPECT_EQ(view.voxelModel, core::RenderSettings{}.voxelModel);
    EXPECT_EQ(ui::RenderingPanel::spectrumSettings(model.rendering(), view.kernel),
              core::RenderSettings{}.toPreprocessOptions());
    // The panel offers exactly the sizes the CLI accepts.
    ui::RenderingPanel panel;
    ASSERT_EQ(panel.sizeCombo()->count(), int(core::settingsSizes().size()));
    for (int i = 0; i < panel.sizeCombo()->count(); ++i)
        EXPECT_EQ(panel.sizeCombo()->itemData(i).toInt(), core::settingsSizes()[std::size_t(i)]);
}

TEST(RenderSettings, ChoicesAreSavedByNameAndReadBack) {
    test::app();
    ScratchSettings scratch;
    ui::RenderingPanel::Values v;
    v.kernel = core::Kernel::Sinc4;
    v.transform = core::TransformKind::Fht;
    v.mapping = core::ValueMapping::MuBone;
    v.voxelModel = core::VoxelModel::BSpline;
    ui::RenderingPanel::save(scratch.settings, v);
    ui::XrayPanel::Values x;
    x.output = ui::XrayOutput::Polychromatic;
    ui::XrayPanel::save(scratch.settings, x);
    QSettings& s = scratch.settings;
    EXPECT_EQ(s.value(ui::keys::kRenderKernel).toString(), "sinc4");
    EXPECT_EQ(s.value(ui::keys::kRenderTransform).toString(), "fht");
    EXPECT_EQ(s.value(ui::keys::kRenderValues).toString(), "mu-bone");
    EXPECT_EQ(s.value(ui::keys::kRenderVoxelModel).toString(), "bspline");
    EXPECT_EQ(s.value(ui::keys::kXrayOutput).toString(), "polychromatic");
    EXPECT_EQ(ui::RenderingPanel::load(s), v);
    EXPECT_EQ(ui::XrayPanel::load(s).output, ui::XrayOutput::Polychromatic);
}

TEST(RenderSettings, NumbersEarlierVersionsSavedStillLoad) {
    test::app();
    ScratchSettings scratch;
    QSettings& s = scratch.settings;
    // As 2026-11 builds wrote them: enum numbers (kernels in allKernels' order).
    s.setValue(ui::keys::kRenderKernel, int(core::Kernel::CatmullRom));
    s.setValue(ui::keys::kRenderTransform, 1);
    s.setValue(ui::keys::kRenderValues, 2);
    s.setValue(ui::keys::kXrayOutput, 1);
    s.sync(); // and read back from the file, as the next start reads it (text, not ints)
    const QSettings file(scratch.dir.filePath("s.ini"), QSettings::IniFormat);
    ui::RenderingPanel::Values v = ui::RenderingPanel::load(file);
    EXPECT_EQ(v.kernel, core::Kernel::CatmullRom);
    EXPECT_EQ(ui::XrayPanel::load(file).output, ui::XrayOutput::Transmission);
    v = ui::RenderingPanel::load(s);
    EXPECT_EQ(v.kernel, core::Kernel::CatmullRom);
    EXPECT_EQ(v.transform, core::TransformKind::Fht);
    EXPECT_EQ(v.mapping, core::ValueMapping::MuBone);
    EXPECT_EQ(ui::XrayPanel::load(s).output, ui::XrayOutput::Transmission);
    // A number or name out of range, or a size not offered: the defaults, never a bad enum.
    s.setValue(ui::keys::kRenderKernel, 42);
    s.setValue(ui::keys::kRenderValues, "attenuation");
    s.setValue(ui::keys::kRenderSize, 300);
    s.setValue(ui::keys::kXrayOutput, "x-ray");
    v = ui::RenderingPanel::load(s);
    EXPECT_EQ(v.kernel, core::RenderSettings{}.kernel);
    EXPECT_EQ(v.mapping, core::RenderSettings{}.values);
    EXPECT_EQ(v.size, core::RenderSettings{}.size);
    EXPECT_EQ(ui::XrayPanel::load(s).output, core::RenderSettings{}.output);
}

} // namespace
