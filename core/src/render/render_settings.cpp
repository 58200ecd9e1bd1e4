// The one home of every rendering choice and its defaults (render_settings.h).
#include <fvr/core/render/render_settings.h>

#include <algorithm>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {

const char* xrayOutputName(XrayOutput o) {
    switch (o) {
    case XrayOutput::LineIntegrals: return "line-integrals";
    case XrayOutput::Transmission: return "transmission";
    case XrayOutput::Polychromatic: return "polychromatic";
    }
    return "?";
}

XrayOutput parseXrayOutput(const std::string& s) {
    for (XrayOutput o :
         {XrayOutput::LineIntegrals, XrayOutput::Transmission, XrayOutput::Polychromatic})
        if (s == xrayOutputName(o)) return o;
    throw SettingsError("X-ray output: expected line-integrals, transmission or polychromatic, "
                        "found '" +
                        s + "'");
}

RenderSettings RenderSettings::preset(std::string_view name) {
    RenderSettings s;
    if (name == "default") return s;
    if (name == "paper") {
        s.kernel = Kernel::Linear;
        s.deapodize = false;
        s.oversampling = 1.0;
        s.values = ValueMapping::Raw;
        s.voxelModel = VoxelModel::BandLimited;
        s.clip = false;
        s.nonNegative = false;
        return s;
    }
    throw SettingsError("preset: expected default or paper, found '" + std::string(name) + "'");
}

std::vector<std::string> RenderSettings::presetNames() { return {"default", "paper"}; }

RenderSettings RenderSettings::forVolume(const Volume& volume, std::string* note) const {
    RenderSettings s = *this;
    if (note) note->clear();
    if (isAttenuation(values) && volume.units != ValueUnits::HounsfieldUnits) {
        s.values = ValueMapping::Raw;
        // A transmission needs attenuation: raw values of unknown units have no mu of water.
        if (s.output == XrayOutput::Transmission) s.output = XrayOutput::LineIntegrals;
        if (note)
            *note = std::string("the values are not Hounsfield units (") + unitsName(volume.units) +
                    "): integrating the raw values instead of attenuation";
    }
    return s;
}

Transmission RenderSettings::beam() const {
    return {muWaterPerMm ? *muWaterPerMm : waterAttenuationPerMm(energyKeV), exposure};
}

bool RenderSettings::griddingCorrected() const {
    return deapodize.value_or(griddingCorrectionHelps(kernel));
}

PreprocessOptions RenderSettings::toPreprocessOptions() const {
    PreprocessOptions po;
    po.mapping = values;
    po.transform = transform;
    po.oversampling = oversampling;
    if (griddingCorrected()) po.deapodizeFor = kernel;
    return po;
}

RenderParams RenderSettings::toRenderParams(const ViewFrame& frame,
                                            const ImageGeometry& image) const {
    RenderParams p{frame, image, kernel};
    p.depthCue = depthCue;
    p.filter = filter;
    p.clipToVolume = clip;
    p.voxelModel = voxelModel;
    p.pixelAperture = pixelAperture;
    p.nonNegative = nonNegative;
    return p;
}

ImageGeometry RenderSettings::imageGeometry(const Volume& volume) const {
    const int shortSide = height > 0 ? std::min(size, height) : size;
    const ImageGeometry g{
        size, pixelSize ? *pixelSize : defaultPixelSize(volume.dims, volume.spacing, shortSide),
        height};
    validateImageGeometry(g, volume.dims, volume.spacing);
    return g;
}

void validateSettingsSize(int size, const std::string& what) {
    if (size < RenderSettings::kMinImage || size > RenderSettings::kMaxImage)
        throw SettingsError(what + ": expected " + std::to_string(RenderSettings::kMinImage) +
                            ".." + std::to_string(RenderSettings::kMaxImage) + " pixels, found " +
                            std::to_string(size));
}

std::pair<int, int> parseImageSize(const std::string& text, const std::string& what) {
    const auto whole = [&](const std::string& t) {
        const auto v = parseNumber<int>(t);
        if (!v)
            throw SettingsError(what + ": expected N or WxH in pixels (" +
                                std::to_string(RenderSettings::kMinImage) + ".." +
                                std::to_string(RenderSettings::kMaxImage) + " each), found '" +
                                text + "'");
        validateSettingsSize(*v, what);
        return *v;
    };
    const auto x = asciiLower(text).find('x');
    if (x == std::string::npos) return {whole(text), whole(text)};
    return {whole(text.substr(0, x)), whole(text.substr(x + 1))};
}

std::vector<int> settingsSizes() {
    std::vector<int> out;
    for (int m = RenderSettings::kMinSize; m <= RenderSettings::kMaxSize; m *= 2) out.push_back(m);
    return out;
}

} // namespace fvr::core
