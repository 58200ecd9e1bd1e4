// Progressive refinement: the level follows simulated frame times while the user drags and
// returns to full quality when the drag ends.
#include <gtest/gtest.h>

#include <fvr/core/render/progressive.h>

using namespace fvr::core;

TEST(Progressive, LevelsDropSizeAndTheKernelOnlyWhenAllowed) {
    const auto locked = progressiveLevels(512, Kernel::KaiserBessel4, true);
    ASSERT_EQ(locked.size(), 4u);
    EXPECT_EQ(locked[0], (QualityLevel{512, Kernel::KaiserBessel4}));
    EXPECT_EQ(locked[1], (QualityLevel{256, Kernel::KaiserBessel4}));
    EXPECT_EQ(locked[3], (QualityLevel{64, Kernel::KaiserBessel4}));
    const auto free = progressiveLevels(512, Kernel::CatmullRom, false);
    ASSERT_EQ(free.size(), 5u);
    EXPECT_EQ(free[1], (QualityLevel{512, Kernel::Linear}));
    EXPECT_EQ(free[2], (QualityLevel{256, Kernel::Linear}));
    EXPECT_EQ(progressiveLevels(256, Kernel::Linear, false).size(), 3u); // 256, 128, 64
    EXPECT_EQ(progressiveLevels(64, Kernel::Nearest, false).size(), 1u);
}

TEST(Progressive, SlowFramesDropLevelsAndReleaseRestoresFullQuality) {
    ProgressiveController c(25.0); // budget 40 ms
    c.setLevels(progressiveLevels(1024, Kernel::KaiserBessel6, true));
    EXPECT_EQ(c.level(), 0);
    c.frameRendered(120.0); // not interacting: still-image frames never drop quality
    EXPECT_EQ(c.level(), 0);
    c.beginInteraction();
    // 120 ms at 1024 predicts 30 ms at 512: the drag starts at level 1.
    EXPECT_EQ(c.level(), 1);
    EXPECT_EQ(c.current().size, 512);
    c.frameRendered(55.0); // slower than predicted: one more level down
    EXPECT_EQ(c.level(), 2);
    EXPECT_EQ(c.describe(), "interactive 2/4: 256\u00b2 kaiser-bessel6");
    c.frameRendered(12.0); // level 1 measured 55 ms: stay
    EXPECT_EQ(c.level(), 2);
    c.endInteraction();
    EXPECT_EQ(c.level(), 0);
    EXPECT_EQ(c.describe(), "full quality");
}

TEST(Progressive, AHiccupDoesNotLockTheDragAtLowQuality) {
    ProgressiveController c(30.0); // 33.3 ms
    c.setLevels(progressiveLevels(512, Kernel::KaiserBessel4, true));
    c.frameRendered(15.0); // a still frame at full quality
    c.beginInteraction();
    EXPECT_EQ(c.level(), 0);
    c.frameRendered(15.0);
    EXPECT_EQ(c.level(), 0);
    c.frameRendered(90.0); // hiccup (another program): drop
    EXPECT_EQ(c.level(), 1);
    // Level 0 now remembers (15 + 90) / 2 = 52.5 ms; fast 4 ms frames at 256 predict 16 ms for
    // 512 and pull the memory down 20 % per frame until it is under 70 % of the budget.
    int frames = 0;
    while (c.level() == 1 && frames < 20) c.frameRendered(4.0), ++frames;
    EXPECT_EQ(c.level(), 0);
    EXPECT_GT(frames, 2);
    EXPECT_LT(frames, 10);
    // A really slow level 0 drops again at once.
    c.frameRendered(60.0);
    EXPECT_EQ(c.level(), 1);
}

TEST(Progressive, AKernelLevelIsTriedNotGuessedFromTheCostlierKernel) {
    // Catmull-Rom 512: 60 ms, linear 512: 15 ms, linear 256: 4 ms, target 30 fps (33 ms).
    ProgressiveController c(30.0);
    c.setLevels(progressiveLevels(512, Kernel::CatmullRom, false)); // CR 512, lin 512, lin 256, ...
    c.frameRendered(60.0); // the still frame
    c.beginInteraction();
    EXPECT_EQ(c.level(), 1); // 512 linear: unmeasured, so tried (not assumed to cost 60 ms)
    std::string trace;
    for (int i = 0; i < 30; ++i) {
        c.frameRendered(c.level() == 0 ? 60.0 : c.level() == 1 ? 15.0 : 4.0);
        trace += char('0' + c.level());
    }
    EXPECT_EQ(trace, std::string(30, '1')) << trace; // holds 512 linear, no 60 ms frames
}

TEST(Progressive, DisabledNeverDrops) {
    ProgressiveController off(0.0);
    off.setLevels(progressiveLevels(512, Kernel::CatmullRom, false));
    off.beginInteraction();
    off.frameRendered(500.0);
    EXPECT_EQ(off.level(), 0);
    EXPECT_FALSE(off.enabled());
}
