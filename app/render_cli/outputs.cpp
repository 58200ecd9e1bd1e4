// fvr-render --out: the views, the image files and the JSON sidecar.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>

#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/xray/display_window.h>

#include "session.h"

namespace fvr::cli {

std::vector<core::ViewFrame> readViewsFile(const std::string& path) {
    using core::SettingsError;
    std::ifstream in(path);
    if (!in) throw core::LoadError(path + ": cannot open the views file");
    std::vector<core::ViewFrame> views;
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
        ++n;
        if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream ss(line);
        std::vector<double> v;
        double x;
        while (ss >> x) v.push_back(x);
        if (!ss.eof()) throw SettingsError(path + ":" + std::to_string(n) + ": expected numbers");
        if (v.empty()) continue;
        if (v.size() != 6)
            throw SettingsError(path + ":" + std::to_string(n) +
                                ": expected 6 numbers (dx dy dz ux uy uz), found " +
                                std::to_string(v.size()));
        try {
            views.push_back(core::ViewFrame::fromDirUp({v[0], v[1], v[2]}, {v[3], v[4], v[5]}));
        } catch (const SettingsError& e) {
            throw SettingsError(path + ":" + std::to_string(n) + ": " + e.what());
        }
    }
    if (views.empty()) throw SettingsError(path + ": no views in the file");
    return views;
}

namespace {

using namespace fvr::core;

std::string numberText(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

/** FILE.ext -> FILE_0007.ext */
std::string numberedPath(const std::string& out, std::size_t i) {
    const std::filesystem::path p(out);
    char num[16];
    std::snprintf(num, sizeof num, "_%04zu", i);
    return (p.parent_path() / (p.stem().string() + num + p.extension().string())).string();
}

/** --sweep about --axis (default: the volume's head-feet axis), the views file, else the one view.
 */
std::vector<ViewFrame> outputViews(const Session& s, const std::vector<ViewFrame>& fileViews) {
    const Options& o = s.options;
    if (o.sweep > 0) {
        const auto& dir = s.volume.direction;
        const Vec3 axis = o.axis ? *o.axis : Vec3{dir[0][2], dir[1][2], dir[2][2]}; // head-feet
        std::vector<ViewFrame> views;
        for (int i = 0; i < o.sweep; ++i)
            views.push_back(s.base.rotated(axis, 2.0 * std::numbers::pi * i / o.sweep));
        return views;
    }
    if (!o.viewsFile.empty()) return fileViews;
    return {s.base};
}

/** What the output's pixels hold. */
std::string valuesText(const Session& s) {
    return s.options.beerLambert ? "transmitted intensity exposure x exp(-mu_water x line integral)"
                                 : projectionUnits(s.options.values, s.volume.units);
}

/** Writes the views one by one, or gathers them into one .npy stack. */
class ViewWriter {
public:
    ViewWriter(const Session& s, std::size_t viewCount, DicomExportInfo exportInfo)
        : m_o(s.options), m_count(viewCount), m_exportInfo(std::move(exportInfo)),
          m_stacked(viewCount > 1 && m_o.format == OutputFormat::Npy && !m_o.numbered) {}

    bool stacked() const { return m_stacked; }
    const std::vector<std::string>& written() const { return m_written; }

    void add(std::size_t i, ProjectionImage img) {
        // Line integrals in the image; transmission where --beer-lambert asks for it.
        std::optional<DisplayWindow> film;
        std::vector<float> lineIntegrals;
        if (m_o.beerLambert && m_o.format == OutputFormat::Png) {
            lineIntegrals = img.pixels;
            // A Beer-Lambert PNG shows the film, as the workstation does: the window on the log
            // exposure, bone white (the float outputs hold the intensity itself).
            film = core::filmWindow(lineIntegrals, m_o.transmission, true);
        }
        if (m_o.beerLambert) applyTransmission(img.pixels, m_o.transmission);
        if (m_stacked) {
            if (m_stack.empty()) m_stack.reserve(m_count * img.pixels.size());
            m_stack.insert(m_stack.end(), img.pixels.begin(), img.pixels.end());
            return;
        }
        const std::string path = m_count > 1 ? numberedPath(m_o.out, i) : m_o.out;
        const int M = m_o.size;
        if (m_o.format == OutputFormat::Png)
            writePng(path, film ? lineIntegrals.data() : img.pixels.data(), M, M,
                     film ? *film : autoWindow(img.pixels), m_o.bitDepth);
        else if (m_o.format == OutputFormat::Dicom)
            writeDicomProjection(path, img, m_exportInfo);
        else
            writeProjection(path, img);
        m_written.push_back(path);
    }

    void finish() {
        if (!m_stacked) return;
        writeNpy(m_o.out, m_stack.data(), m_o.size, m_o.size, std::int64_t(m_count));
        m_written.push_back(m_o.out);
    }

private:
    const Options& m_o;
    std::size_t m_count;
    DicomExportInfo m_exportInfo;
    bool m_stacked;
    std::vector<float> m_stack;
    std::vector<std::string> m_written;
};

/** The DICOM outputs' value description: the values, depth cue and slice filter. */
DicomExportInfo dicomInfo(const Session& s, DicomExportInfo info) {
    info.valueDescription = valuesText(s);
    if (s.options.depthCue > 0)
        info.valueDescription += "; depth cue " + numberText(s.options.depthCue);
    if (s.options.filter.active())
        info.valueDescription += "; slice-filtered (sharpen, band limit)";
    return info;
}

/** Renders and writes every view with a progress line; returns the time per view in ms. */
double renderViews(const Session& s, const std::vector<ViewFrame>& views, ViewWriter& writer) {
    const auto t0 = std::chrono::steady_clock::now();
    auto lastReport = t0;
    for (std::size_t i = 0; i < views.size(); ++i) {
        writer.add(i, s.backend.renderer().render(s.params(views[i])));
        const auto now = std::chrono::steady_clock::now();
        if (views.size() > 1 &&
            (now - lastReport > std::chrono::seconds(1) || i + 1 == views.size())) {
            std::fprintf(stderr, "%sview %zu/%zu%s", isatty(2) ? "\r" : "", i + 1, views.size(),
                         isatty(2) ? "" : "\n");
            lastReport = now;
        }
    }
    if (views.size() > 1 && isatty(2)) std::fprintf(stderr, "\n");
    writer.finish();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
               .count() /
           double(views.size());
}

void printSummary(const Session& s, std::size_t viewCount, bool stacked, double msPerView) {
    const Options& o = s.options;
    const bool one = stacked || viewCount == 1;
    std::fprintf(
        stderr, "wrote %s%s (%zu view%s, %dx%d, pixel %.4g mm, %s, %s, %s, %s; %.2f ms per view)\n",
        one ? o.out.c_str() : numberedPath(o.out, 0).c_str(), one ? "" : " ...", viewCount,
        viewCount > 1 ? "s" : "", o.size, o.size, s.geometry.pixelSize, kernelName(o.kernel),
        transformName(o.transform),
        o.beerLambert ? "transmission" : projectionUnits(o.values, s.volume.units).c_str(),
        s.backend.name().c_str(), msPerView);
}

} // namespace

void writeOutputs(const Session& s, const std::vector<ViewFrame>& fileViews,
                  const DicomExportInfo& exportInfo) {
    const std::vector<ViewFrame> views = outputViews(s, fileViews);
    ViewWriter writer(s, views.size(), dicomInfo(s, exportInfo));
    const double msPerView = renderViews(s, views, writer);
    // JSON sidecar: every parameter, so the output can be reproduced and registered.
    const WrittenOutput output{valuesText(s), writer.stacked(), writer.written(), s.preprocessMs,
                               msPerView};
    writeFileAtomic(s.options.out + ".json",
                    jsonText(sidecarJson(s.facts(), s.volume, output, views)));
    printSummary(s, views.size(), writer.stacked(), msPerView);
}

} // namespace fvr::cli
