// fvr-render --out: the views, the image files and the JSON sidecar.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <exception>
#include <fstream>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/patient_views.h>

#include "cone.h"
#include "output_files.h"
#include "pacs.h"
#include "session.h"

namespace fvr::cli {

namespace {

std::vector<core::ViewFrame> sweepViews(const Options& o, const core::Volume& volume,
                                        const core::ViewFrame& base) {
    using namespace fvr::core;
    const auto& dir = volume.direction;
    const Vec3 axis = o.axis ? *o.axis : Vec3{dir[0][2], dir[1][2], dir[2][2]}; // head-feet
    // Views along the axis would all be one projection turned in the image plane: the default
    // view gives way to the first of AP, LEFT and HEAD that looks across the axis.
    auto alongAxis = [&](const ViewFrame& v) {
        return std::abs(glm::dot(v.d, axis)) > 0.999 * glm::length(v.d) * glm::length(axis);
    };
    ViewFrame start = base;
    for (PatientView pv : {PatientView::AP, PatientView::Left, PatientView::Head})
        if (alongAxis(start) && !o.viewGiven) start = patientViewFrame(volume, pv);
    if (alongAxis(start))
        throw SettingsError("--sweep: the view looks along the rotation axis, so every view would "
                            "be the same projection turned in the image plane; give a --view "
                            "(AP, LEFT, ...) or a --dir across the axis, or another --axis");
    std::vector<ViewFrame> views;
    for (int i = 0; i < o.sweep; ++i)
        views.push_back(start.rotated(axis, 2.0 * std::numbers::pi * i / o.sweep));
    return views;
}

} // namespace

std::vector<core::ViewFrame> outputViews(const Options& o, const core::Volume& volume,
                                         const core::ViewFrame& base,
                                         const std::vector<core::ViewFrame>& fileViews) {
    if (o.sweep > 0) return sweepViews(o, volume, base);
    if (!o.viewsFile.empty()) return fileViews;
    return {base};
}

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

/** What the output's pixels hold. */
std::string valuesText(const Options& o, const Volume& volume) {
    return o.beerLambert ? "transmitted intensity exposure x exp(-mu_water x line integral)"
                         : projectionUnits(o.settings.values, volume.units);
}
std::string valuesText(const Session& s) { return valuesText(s.options, s.volume); }

/** The name of --send's temporary folders (.fvr-render-send.PID-ID.N.part in the temporary folder).
 */
constexpr const char* kSendFolder = "fvr-render-send";

/** Writes the views (width x height images) one by one, or streams them into one .npy stack
 *  (written as it is produced, header first), all into `files`' staging folder (committed with
 *  the sidecar, not here). */
class ViewWriter {
public:
    ViewWriter(const Options& o, OutputFiles& files, std::size_t viewCount, int width, int height,
               DicomExportInfo exportInfo)
        : m_o(o), m_files(files), m_count(viewCount), m_width(width), m_height(height),
          m_exportInfo(std::move(exportInfo)),
          m_stacked(viewCount > 1 && m_o.format == OutputFormat::Npy && !m_o.numbered) {
        // One run is one new series: its views are its instances 1..n.
        m_exportInfo.seriesInstanceUid = core::newSeriesInstanceUid();
        m_exportInfo.seriesNumber = core::newExportSeriesNumber();
        // Opened before the first view is rendered: an unwritable path fails at once.
        if (m_stacked) {
            const auto at = m_files.staged(m_o.out);
            finalNamesOnError([&] {
                m_stack =
                    std::make_unique<NpyStackWriter>(at, m_height, m_width, std::int64_t(m_count));
            });
        }
    }

    /** View i's DICOM identity: the run's one series, instance i + 1. */
    DicomExportInfo infoFor(std::size_t i) const {
        DicomExportInfo info = m_exportInfo;
        info.instanceNumber = int(i) + 1;
        return info;
    }

    /** Runs `write`; its WriteError says the final path, not the staged one. */
    template <class Write>
    void finalNamesOnError(Write&& write) {
        try {
            write();
        } catch (const WriteError& e) {
            throw WriteError(m_files.finalNames(e.what()));
        }
    }

    /** One file holds every view: a .npy stack, or a cone-beam run as one multi-frame XA. */
    bool stacked() const { return m_stacked || (m_coneDicom && m_coneDicom->run); }
    const std::vector<std::string>& written() const { return m_written; }

    /** Post-processes and writes view i (the writer thread calls it, in view order). */
    void add(std::size_t i, ProjectionImage& img) {
        core::checkFiniteImage(img); // never a NaN in a file
        addPixels(i, img.pixels, &img);
    }
    /** A cone-beam view: as its format says, and for --send as an X-ray of its C-arm. */
    void add(std::size_t i, DetectorImage& img) {
        for (float v : img.pixels)
            if (!std::isfinite(v))
                throw RenderError("a cone-beam view holds a value that is not finite");
        if (m_o.format == OutputFormat::Dicom && m_coneDicom) {
            addConeDicom(i, img);
            return;
        }
        addPixels(i, img.pixels, nullptr); // the pixels now as written (transmission)
        if (!m_o.send.empty() && m_coneDicom) { // --send: an X-ray of its C-arm, or an RT Image
            m_toSend.push_back(sendPath(i));
            if (!m_coneDicom->beams.empty())
                writeRtImageDicom(m_toSend.back(), img, m_coneDicom->beams.at(i), infoFor(i));
            else
                writeXrayDicom(m_toSend.back(), img, m_coneDicom->arms.at(i), infoFor(i));
        }
    }

    /** Cone-beam views written as X-ray images carrying `dicom`'s C-arms, or RT Images carrying
     *  its treatment beams (set before the first view). */
    void setConeDicom(const ConeDicom& dicom) { m_coneDicom = &dicom; }
    /** What --send stores: Secondary Captures of parallel views, X-rays of C-arms or RT Images
     *  of treatment beams. */
    const char* sentKind() const {
        if (!m_coneDicom) return "Secondary Capture";
        return m_coneDicom->beams.empty() ? "X-Ray Angiographic" : "RT Image";
    }

    /** A cone-beam view as an X-Ray Angiographic image: its own file, or a frame of the run
     *  written by finish(). */
    void addConeDicom(std::size_t i, DetectorImage& img) {
        if (m_o.beerLambert) applyTransmission(img.pixels, m_o.transmission);
        if (!m_coneDicom->beams.empty()) { // a treatment beam: one RT Image each
            const std::string path = m_count > 1 ? numberedPath(m_o.out, i) : m_o.out;
            finalNamesOnError([&] {
                writeRtImageDicom(m_files.staged(path), img, m_coneDicom->beams.at(i), infoFor(i));
            });
            m_written.push_back(path);
            if (!m_o.send.empty()) m_toSend.emplace_back(path); // sent after the commit
            return;
        }
        const CArm& arm = m_coneDicom->arms.at(i);
        if (m_coneDicom->run) {
            if (!m_run.empty()) { // the run's one detector (equal to rounding, cone_xray.cpp)
                const ConeCamera& f = m_run.front().camera;
                img.camera =
                    cArmCamera(arm, f.width, f.height, f.pitchU, f.pitchV, f.principalOffset);
            }
            m_run.push_back(std::move(img));
            return;
        }
        const std::string path = m_count > 1 ? numberedPath(m_o.out, i) : m_o.out;
        finalNamesOnError([&] { writeXrayDicom(m_files.staged(path), img, arm, infoFor(i)); });
        m_written.push_back(path);
        if (!m_o.send.empty()) m_toSend.emplace_back(path); // sent after the commit
    }

    /** The line integrals in `pixels` (transmission where --beer-lambert asks for it) written
     *  as the format says; `img` (null for a cone-beam view) for DICOM and --send. */
    void addPixels(std::size_t i, std::vector<float>& pixels, const ProjectionImage* img) {
        std::optional<DisplayWindow> film;
        if (m_o.beerLambert && m_o.format == OutputFormat::Png) {
            m_lineIntegrals = pixels; // the buffer is reused from view to view
            // A Beer-Lambert PNG shows the film, as the workstation does: the window on the log
            // exposure, bone white (the float outputs hold the intensity itself).
            film = core::filmWindow(m_lineIntegrals, m_o.transmission, true);
        }
        if (m_o.beerLambert) applyTransmission(pixels, m_o.transmission);
        if (m_stacked) {
            finalNamesOnError([&] { m_stack->add(pixels.data()); });
            addToSend(i, m_o.out, img);
            return;
        }
        const std::string path = m_count > 1 ? numberedPath(m_o.out, i) : m_o.out;
        const std::filesystem::path at = m_files.staged(path);
        finalNamesOnError([&] {
            if (m_o.format == OutputFormat::Png)
                writePng(at, film ? m_lineIntegrals.data() : pixels.data(), m_height, m_width,
                         film ? *film : autoWindow(pixels), m_o.bitDepth);
            else if (m_o.format == OutputFormat::Dicom && img)
                writeDicomProjection(at, *img, infoFor(i));
            else if (m_o.format == OutputFormat::Pfm)
                writePfm(at, pixels.data(), m_height, m_width);
            else
                writeNpy(at, pixels.data(), m_height, m_width);
        });
        m_written.push_back(path);
        addToSend(i, path, img); // the final path: sent after the commit
    }

    /** --send: the DICOM outputs themselves, else a Secondary Capture of each view written
     *  into a temporary folder (removed with the writer). */
    void addToSend(std::size_t i, const std::string& path, const ProjectionImage* img) {
        if (m_o.send.empty() || (!img && m_coneDicom)) return; // a cone-beam view: add()
        if (!img) throw RenderError("--send: no DICOM for this view"); // refused by the options
        if (m_o.format == OutputFormat::Dicom) {
            m_toSend.emplace_back(path);
            return;
        }
        m_toSend.push_back(sendPath(i));
        writeDicomProjection(m_toSend.back(), *img, infoFor(i));
    }
    /** Where view i's DICOM for --send is written when the output is not DICOM. */
    std::filesystem::path sendPath(std::size_t i) {
        if (m_sendDir.empty()) {
            // Its own temporary folder (several runs in one process, the Python module's, may
            // send at once); those of runs that died are removed first.
            const auto tmp = std::filesystem::temp_directory_path();
            removeStaleTemporariesOf(tmp, kSendFolder);
            m_sendDir = tmp / temporaryName(kSendFolder);
            std::filesystem::create_directories(m_sendDir);
        }
        return m_sendDir / ("view_" + std::to_string(i) + ".dcm");
    }
    const std::vector<std::filesystem::path>& toSend() const { return m_toSend; }

    ~ViewWriter() {
        std::error_code ec;
        if (!m_sendDir.empty()) std::filesystem::remove_all(m_sendDir, ec);
    }

    void finish() {
        if (!m_run.empty()) { // a rotational run: one multi-frame X-ray
            finalNamesOnError([&] {
                writeXrayDicomRun(m_files.staged(m_o.out), m_run, m_coneDicom->arms, m_exportInfo);
            });
            m_written.push_back(m_o.out);
            if (!m_o.send.empty()) m_toSend.emplace_back(m_o.out);
        }
        if (!m_stacked) return;
        finalNamesOnError([&] { m_stack->finish(); });
        m_written.push_back(m_o.out);
    }

private:
    const Options& m_o;
    OutputFiles& m_files;
    std::size_t m_count;
    int m_width, m_height;
    DicomExportInfo m_exportInfo;
    bool m_stacked;
    std::unique_ptr<NpyStackWriter> m_stack;
    std::filesystem::path m_sendDir;
    std::vector<std::filesystem::path> m_toSend;
    std::vector<float> m_lineIntegrals;
    std::vector<std::string> m_written;
    const ConeDicom* m_coneDicom = nullptr;
    std::vector<DetectorImage> m_run; ///< a cone-beam run's views, written by finish()
};

/**
 * The writer thread: ViewWriter::add runs here, a few views behind the render loop, so that the
 * loop renders view i+1 while view i is post-processed and written. The queue is bounded
 * (kQueued views wait at most), so that the images in memory stay few whatever the view count.
 * A writer error makes the next push() return false (the loop stops) and finish() rethrow it.
 * Image: ProjectionImage (parallel views) or DetectorImage (cone beam).
 */
template <class Image>
class WriterThread {
public:
    static constexpr std::size_t kQueued = 3;

    explicit WriterThread(ViewWriter& writer) : m_writer(writer), m_thread([this] { loop(); }) {}

    /** Stops the writer where it is (an exception in the render loop) and waits for it. */
    ~WriterThread() {
        {
            std::lock_guard lock(m_mutex);
            m_closed = m_cancelled = true;
        }
        m_changed.notify_all();
        if (m_thread.joinable()) m_thread.join();
    }

    WriterThread(const WriterThread&) = delete;
    WriterThread& operator=(const WriterThread&) = delete;

    /** Queues view i, waiting while the queue is full; false once the writer has failed. */
    bool push(std::size_t i, Image img) {
        std::unique_lock lock(m_mutex);
        m_changed.wait(lock, [&] { return m_queue.size() < kQueued || m_error; });
        if (m_error) return false;
        m_queue.emplace_back(i, std::move(img));
        m_changed.notify_all();
        return true;
    }

    /** Waits until every queued view is written; rethrows the writer's error. */
    void finish() {
        {
            std::lock_guard lock(m_mutex);
            m_closed = true;
        }
        m_changed.notify_all();
        m_thread.join();
        if (m_error) std::rethrow_exception(m_error);
    }

private:
    void loop() {
        for (;;) {
            std::pair<std::size_t, Image> item;
            {
                std::unique_lock lock(m_mutex);
                m_changed.wait(lock, [&] { return !m_queue.empty() || m_closed; });
                if (m_cancelled || m_queue.empty()) return;
                item = std::move(m_queue.front());
                m_queue.pop_front();
            }
            m_changed.notify_all(); // room in the queue
            try {
                m_writer.add(item.first, item.second);
            } catch (...) {
                std::lock_guard lock(m_mutex);
                m_error = std::current_exception();
                m_queue.clear();
                m_changed.notify_all();
                return;
            }
        }
    }

    ViewWriter& m_writer;
    std::mutex m_mutex;
    std::condition_variable m_changed;
    std::deque<std::pair<std::size_t, Image>> m_queue;
    bool m_closed = false, m_cancelled = false;
    std::exception_ptr m_error;
    std::thread m_thread; // last: started when the rest is ready
};

/** The DICOM outputs' value description: the values, depth cue and slice filter. */
DicomExportInfo dicomInfo(const Session& s, DicomExportInfo info) {
    info.valueDescription = valuesText(s);
    // PatientOrientation of each view, where the volume says where the patient is.
    if (s.volume.orientationStated) info.patientDirection = s.volume.direction;
    if (s.options.settings.depthCue > 0)
        info.valueDescription += "; depth cue " + numberText(s.options.settings.depthCue);
    if (s.options.settings.filter.active())
        info.valueDescription += "; slice-filtered (sharpen, band limit)";
    return info;
}

/** Renders `count` views with a progress line while the writer thread writes them; `render`
 *  (first, n) returns views first..first+n-1, `batch` at a time. Returns the wall time from the
 *  first render to the last byte written, per view, in ms. */
template <class Image, class Render>
double renderViews(const Options& o, std::size_t count, std::size_t batch, Render render,
                   ViewWriter& writer) {
    const auto t0 = std::chrono::steady_clock::now();
    auto lastReport = t0;
    WriterThread<Image> writerThread(writer);
    const std::size_t width = std::max<std::size_t>(1, batch);
    std::vector<Image> images;
    for (std::size_t i = 0; i < count; ++i) {
        if (i % width == 0) images = render(i, std::min(count, i + width) - i); // the next views
        if (!writerThread.push(i, std::move(images[i % width])))
            break; // the writer failed: finish() says why
        if (InterruptGuard::signal() != 0) {
            if (count > 1 && isatty(2)) std::fprintf(stderr, "\n");
            std::string what =
                "interrupted after view " + std::to_string(i + 1) + " of " + std::to_string(count);
            // The staged files go (the writer thread stops first): all or nothing.
            throw Interrupted(what + ": " + o.out +
                              " not written (nothing of this run is kept; an earlier run's "
                              "files stay as they were)");
        }
        const auto now = std::chrono::steady_clock::now();
        if (count > 1 && (now - lastReport > std::chrono::seconds(1) || i + 1 == count)) {
            std::fprintf(stderr, "%sview %zu/%zu%s", isatty(2) ? "\r" : "", i + 1, count,
                         isatty(2) ? "" : "\n");
            lastReport = now;
        }
    }
    if (count > 1 && isatty(2)) std::fprintf(stderr, "\n");
    writerThread.finish();
    writer.finish();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
               .count() /
           double(count);
}

/** The views of a Fourier-rendered run (one per CPU thread at once). */
double renderViews(const Session& s, const std::vector<ViewFrame>& views, ViewWriter& writer) {
    return renderViews<ProjectionImage>(
        s.options, views.size(), std::size_t(std::max(1, s.backend.batchWidth())),
        [&](std::size_t first, std::size_t n) {
            std::vector<RenderParams> params;
            for (std::size_t j = first; j < first + n; ++j) params.push_back(s.params(views[j]));
            return s.backend.renderBatch(params);
        },
        writer);
}

void printSummary(const Session& s, std::size_t viewCount, bool stacked, double msPerView) {
    const Options& o = s.options;
    const bool one = stacked || viewCount == 1;
    std::fprintf(
        stderr, "wrote %s%s (%zu view%s, %dx%d, pixel %.4g mm, %s, %s, %s, %s; %.2f ms per view)\n",
        one ? o.out.c_str() : numberedPath(o.out, 0).c_str(), one ? "" : " ...", viewCount,
        viewCount > 1 ? "s" : "", s.geometry.cols(), s.geometry.rows(), s.geometry.pixelSize,
        kernelName(o.settings.kernel), transformName(o.settings.transform),
        o.beerLambert ? "transmission" : projectionUnits(o.settings.values, s.volume.units).c_str(),
        s.backend.name().c_str(), msPerView);
}

} // namespace

namespace {

/** One --out run: renders the views into the writer (`render` returns the time per view),
 *  writes the sidecar (`sidecar` of the written output) and commits all of it together, says
 *  what it wrote (`summary`(stacked, ms per view)) and sends the views where --send asks. */
template <class Render, class Sidecar, class Summary>
void writeRun(const Options& o, std::size_t viewCount, int width, int height,
              DicomExportInfo exportInfo, Render render, Sidecar sidecar, Summary summary) {
    InterruptGuard interrupt; // before the writer opens its files
    std::string interrupted = "interrupted after the last view"; // the files are complete
    try {
        OutputFiles files(o.out);
        ViewWriter writer(o, files, viewCount, width, height, std::move(exportInfo));
        const double msPerView = render(writer);
        // JSON sidecar: every parameter, so the output can be reproduced and registered.
        const Json json = sidecar(writer, msPerView);
        writer.finalNamesOnError(
            [&] { writeFileAtomic(files.staged(o.out + ".json"), jsonText(json)); });
        files.commit(); // the images and their sidecar land together
        summary(writer.stacked(), msPerView);
        if (!o.send.empty())
            sendViews(o, writer.toSend(), writer.sentKind(), o.cone.enabled ? "file" : "view");
    } catch (const Interrupted& e) {
        interrupted = e.what();
    }
    interrupt.dieIfInterrupted(interrupted);
}

} // namespace

void writeOutputs(const Session& s, const std::vector<ViewFrame>& views,
                  const DicomExportInfo& exportInfo) {
    writeRun(
        s.options, views.size(), s.geometry.cols(), s.geometry.rows(), dicomInfo(s, exportInfo),
        [&](ViewWriter& writer) { return renderViews(s, views, writer); },
        [&](const ViewWriter& writer, double msPerView) {
            const WrittenOutput output{valuesText(s), writer.stacked(), writer.written(),
                                       s.preprocessMs, msPerView};
            return sidecarJson(s.facts(), s.volume, output, views);
        },
        [&](bool stacked, double msPerView) { printSummary(s, views.size(), stacked, msPerView); });
}

void writeConeOutputs(const ConeSession& s, const std::vector<ConeView>& views,
                      const ConeDicom& dicom) {
    const Options& o = s.options;
    const ConeCamera& first = views.front().camera;
    DicomExportInfo info = s.exportInfo;
    info.valueDescription = valuesText(o, s.volume);
    info.transmission = o.beerLambert;
    writeRun(
        o, views.size(), first.width, first.height, info,
        [&](ViewWriter& writer) {
            if (o.format == OutputFormat::Dicom || !o.send.empty()) writer.setConeDicom(dicom);
            // One view at a time: the projector runs each on every thread.
            return renderViews<DetectorImage>(
                o, views.size(), 1,
                [&](std::size_t i, std::size_t) {
                    return std::vector<DetectorImage>{projectConeView(s, views[i].camera)};
                },
                writer);
        },
        [&](const ViewWriter& writer, double msPerView) {
            const WrittenOutput output{valuesText(o, s.volume), writer.stacked(), writer.written(),
                                       s.prepareMs, msPerView};
            return coneSidecarJson(s, output, views);
        },
        [&](bool stacked, double msPerView) {
            const bool one = stacked || views.size() == 1;
            std::fprintf(stderr,
                         "wrote %s%s (%zu view%s, %dx%d, pitch %.4g x %.4g mm, cone beam, %s, "
                         "%s, %s; %.2f ms per view)\n",
                         one ? o.out.c_str() : numberedPath(o.out, 0).c_str(), one ? "" : " ...",
                         views.size(), views.size() > 1 ? "s" : "", first.width, first.height,
                         first.pitchU, first.pitchV, s.caster.description().c_str(),
                         o.beerLambert ? "transmission" : valuesText(o, s.volume).c_str(),
                         s.caster.name().c_str(), msPerView);
        });
}

} // namespace fvr::cli
