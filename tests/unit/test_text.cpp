// text.h: the one ASCII case folding and the one whole-string number parser that the loaders,
// the DICOM scan, the dicom:// URL and the front ends share.
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/text.h>

using namespace fvr::core;

TEST(Text, AsciiLowerFoldsOnlyAToZ) {
    EXPECT_EQ(asciiLower("DICOMDIR.Nii.GZ"), "dicomdir.nii.gz");
    EXPECT_EQ(asciiLower("met_SHORT @[`{"), "met_short @[`{"); // the bytes around A-Z stay
    // UTF-8 and Latin-1 bytes stay as they are: "ÄÖ" (UTF-8) and a Latin-1 'Ä'.
    EXPECT_EQ(asciiLower("\xC3\x84\xC3\x96X"), "\xC3\x84\xC3\x96x");
    EXPECT_EQ(asciiLower("\xC4"), "\xC4");
    EXPECT_EQ(asciiLower(""), "");
    std::string all;
    for (int c = 0; c < 256; ++c) all += char(c);
    const std::string folded = asciiLower(all);
    ASSERT_EQ(folded.size(), 256u);
    for (int c = 0; c < 256; ++c)
        EXPECT_EQ(static_cast<unsigned char>(folded[std::size_t(c)]),
                  c >= 'A' && c <= 'Z' ? c + 32 : c)
            << "byte " << c;
}

TEST(Text, IequalsAndIstartsWith) {
    EXPECT_TRUE(iequals("LOCAL", "local"));
    EXPECT_TRUE(iequals("", ""));
    EXPECT_FALSE(iequals("local", "locale"));
    EXPECT_FALSE(iequals("\xC4", "\xE4")); // Latin-1 'Ä' and 'ä' are not ASCII
    EXPECT_TRUE(istartsWith("DICOM://AE@host:104", "dicom://"));
    EXPECT_TRUE(istartsWith("dicom://", "dicom://"));
    EXPECT_FALSE(istartsWith("dicom:/", "dicom://"));
    EXPECT_FALSE(istartsWith("http://dicom://", "dicom://"));
}

TEST(Text, TrimSpaceRemovesAsciiWhitespaceOnly) {
    EXPECT_EQ(trimSpace(" \t\r\n\f\vx y\t "), "x y");
    EXPECT_EQ(trimSpace("   "), "");
    EXPECT_EQ(trimSpace("\xA0x\xA0"), "\xA0x\xA0"); // Latin-1 no-break space is not ASCII
}

TEST(Text, ParseNumberReadsTheWholeText) {
    EXPECT_EQ(parseNumber<std::int64_t>("42"), 42);
    EXPECT_EQ(parseNumber<std::int64_t>("  +42\r\n"), 42);
    EXPECT_EQ(parseNumber<std::int64_t>("-7"), -7);
    EXPECT_EQ(parseNumber<int>("2048"), 2048);
    for (const char* bad : {"", "  ", "+", "++1", "+-1", "4 2", "42x", "x42", "0x10", "1.5", "1e3"})
        EXPECT_FALSE(parseNumber<std::int64_t>(bad)) << "'" << bad << "'";
    // Out of range is nullopt, not a wrapped or clamped value.
    EXPECT_EQ(parseNumber<std::int64_t>("9223372036854775807"),
              std::numeric_limits<std::int64_t>::max());
    EXPECT_FALSE(parseNumber<std::int64_t>("9223372036854775808"));
    EXPECT_FALSE(parseNumber<int>("2147483648"));
    EXPECT_FALSE(parseNumber<std::uint16_t>("-1"));
    EXPECT_FALSE(parseNumber<std::uint16_t>("65536"));
}

TEST(Text, ParseNumberReadsDoublesWithoutTheLocale) {
    EXPECT_EQ(parseNumber<double>("0.5"), 0.5);
    EXPECT_EQ(parseNumber<double>(" +1.25e-3 "), 1.25e-3);
    EXPECT_EQ(parseNumber<double>("-2"), -2.0);
    EXPECT_EQ(parseNumber<double>(".5"), 0.5);
    for (const char* bad : {"", "1,5", "0.5mm", "1e", "--1", "0x1p3"})
        EXPECT_FALSE(parseNumber<double>(bad)) << "'" << bad << "'";
    // Not finite, but numbers: callers that need finite values check (parseNumbers does).
    const auto inf = parseNumber<double>("inf");
    ASSERT_TRUE(inf);
    EXPECT_TRUE(std::isinf(*inf));
    const auto nan = parseNumber<double>("nan");
    ASSERT_TRUE(nan);
    EXPECT_TRUE(std::isnan(*nan));
    EXPECT_FALSE(parseNumber<float>("1e39")); // beyond float
}
