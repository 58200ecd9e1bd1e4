// The Python module fvr._fvr: thin pybind11 bindings over fvr::core and fvr-render's own rules
// (render_cli: the settings, their checks and defaults, the views, the run with its sidecar).
// Settings arrive as fvr-render option arguments, so that Python and the CLI cannot disagree.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/projection_matrix_file.h>
#include <fvr/core/io/open_study.h>
#include <fvr/core/registration/registration.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/cpu_batch.h>
#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/patient_views.h>

#include "glm_caster.h"
#include "input.h"
#include "json_output.h"
#include "options.h"
#include "run.h"
#include "session.h"

namespace py = pybind11;
using namespace fvr;

namespace {

using Args = std::vector<std::string>;

/** A volume and what its loader said. */
struct PyVolume {
    std::shared_ptr<const core::Volume> volume;
    std::vector<std::string> warnings;
};

core::ValueUnits unitsFromName(const std::string& name) {
    using core::ValueUnits;
    for (auto u : {ValueUnits::Unknown, ValueUnits::HounsfieldUnits,
                   ValueUnits::LinearAttenuationRelWater, ValueUnits::Intensity})
        if (name == core::unitsName(u)) return u;
    throw core::SettingsError("units: expected unknown, HU, mu/mu_water or intensity, found '" +
                              name + "'");
}

/** A volume from a (z, y, x) array: one copy into the volume's own storage, GIL released. */
PyVolume volumeFromArray(py::array_t<float, py::array::c_style | py::array::forcecast> a,
                         const core::Vec3& spacing, const core::Vec3& origin,
                         const glm::dmat3& direction, const std::string& units,
                         const std::string& name) {
    if (a.ndim() != 3)
        throw core::SettingsError("array: expected 3 dimensions (z, y, x), found " +
                                  std::to_string(a.ndim()));
    auto v = std::make_shared<core::Volume>();
    v->dims = {a.shape(2), a.shape(1), a.shape(0)};
    try {
        core::validateGeometry(v->dims, spacing, name);
    } catch (const core::InputError& e) { // a bad argument here, not a bad file
        throw core::SettingsError(e.what());
    }
    v->spacing = spacing;
    v->origin = origin;
    v->direction = direction;
    v->units = unitsFromName(units);
    v->name = name;
    const float* data = a.data();
    {
        py::gil_scoped_release release;
        v->voxels.assign(data, data + v->voxelCount());
    }
    std::vector<std::string> warnings;
    if (auto w = core::replaceNonFiniteVoxels(*v)) warnings.push_back(*w);
    return PyVolume{std::move(v), std::move(warnings)};
}

/** The settings of a Renderer and its parallel renders: a cone beam is rendered through a
 *  camera (render(camera=...)), whose parts the cone-beam options would give. */
cli::Options rendererSettings(const Args& args) {
    cli::Options o = cli::parseSettings(args);
    if (o.cone.enabled)
        throw core::SettingsError(
            "geometry: a cone beam is rendered with a camera: r.render(camera=fvr.Camera.carm("
            "...)) (the C-arm, detector and pitch are the camera's)");
    // The renderer gives line integrals (and Beer-Lambert through transmission()): a --kvp it
    // took would be a polychromatic setting silently not applied.
    if (o.polychromatic())
        throw core::SettingsError(
            "kvp: fvr.Renderer renders line integrals, not polychromatic images; "
            "fvr.run_cli([..., \"--kvp\", ...]) runs fvr-render --kvp");
    return o;
}

/** fvr.load: the path by core's rule (core::openStudy through fvr-render's loadInput). */
PyVolume load(const std::string& path, const Args& args) {
    cli::Options o = cli::parseSettings(args);
    o.input = path;
    py::gil_scoped_release release;
    cli::LoadedInput in = cli::loadInput(o);
    return PyVolume{std::make_shared<core::Volume>(std::move(*in.volume)), in.warnings};
}

/** The array (z, y, x) viewing the volume's voxels (read-only; keeps the volume alive). */
py::array volumeArray(const PyVolume& v) {
    const auto& d = v.volume->dims;
    auto* owner = new std::shared_ptr<const core::Volume>(v.volume);
    py::capsule base(owner,
                     [](void* p) { delete static_cast<std::shared_ptr<const core::Volume>*>(p); });
    py::array_t<float> a({d[2], d[1], d[0]}, v.volume->voxels.data(), base);
    py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return a;
}

/** An image stack (n, M, M), row 0 at the top as fvr-render's .npy. */
py::array_t<float> imageStack(std::size_t n, int height, int width) {
    return py::array_t<float>({py::ssize_t(n), py::ssize_t(height), py::ssize_t(width)});
}

/** Views from an (N, 2, 3) array of (dir, up) rows. */
std::vector<core::ViewFrame> viewsFromArray(
    py::array_t<double, py::array::c_style | py::array::forcecast> a) {
    if (a.ndim() != 3 || a.shape(1) != 2 || a.shape(2) != 3)
        throw core::SettingsError("views: expected an (N, 2, 3) array of (dir, up), or view names");
    std::vector<core::ViewFrame> views;
    auto r = a.unchecked<3>();
    for (py::ssize_t i = 0; i < a.shape(0); ++i)
        views.push_back(core::ViewFrame::fromDirUp({r(i, 0, 0), r(i, 0, 1), r(i, 0, 2)},
                                                   {r(i, 1, 0), r(i, 1, 1), r(i, 1, 2)}));
    return views;
}

/**
 * fvr.Renderer: the volume's spectrum made once with fvr-render's settings, then views on the
 * CPU (core::CpuBatchRenderer: the batch rule of --sweep). Calls are serialised (one batch
 * renderer); two renderers render concurrently, the GIL released.
 */
class PyRenderer {
public:
    PyRenderer(PyVolume volume, Args args, py::object progress)
        : m_volume(std::move(volume)), m_args(std::move(args)),
          m_options(rendererSettings(m_args)) {
        // As fvr-render: attenuation for Hounsfield data, raw values for any other.
        m_options.settings = m_options.settings.forVolume(*m_volume.volume);
        const core::PreprocessOptions po = cli::preprocessOptions(m_options);
        std::string pyError;
        core::CancelToken cancel;
        core::ProgressFn fn;
        if (!progress.is_none())
            fn = [&](double f, std::string_view stage) {
                py::gil_scoped_acquire gil;
                try {
                    progress(f, std::string(stage));
                } catch (py::error_already_set& e) {
                    pyError = e.what(); // stops the preprocessing at its next check
                    cancel.cancel();
                }
            };
        try {
            py::gil_scoped_release release;
            m_spectrum = core::preprocess(*m_volume.volume, po, fn, &cancel);
            m_batch = std::make_unique<core::CpuBatchRenderer>(m_spectrum, m_options.threads);
        } catch (const core::Cancelled&) {
            throw std::runtime_error("progress callback raised: " + pyError);
        }
    }

    /** One view; `extra` adds view and image settings (--view, --dir, --size...). */
    py::array_t<float> render(const Args& extra) {
        const cli::Options o = options(extra); // the call's view replaces the renderer's
        const core::ImageGeometry g = cli::imageGeometry(o, *m_volume.volume);
        const core::RenderParams p = cli::renderParams(o, cli::baseView(o, *m_volume.volume), g);
        core::validateRenderParams(p);
        auto out = py::array_t<float>({py::ssize_t(g.rows()), py::ssize_t(g.cols())});
        float* dst = out.mutable_data();
        py::gil_scoped_release release;
        std::lock_guard lock(m_mutex);
        const auto images = m_batch->renderBatch({p});
        std::memcpy(dst, images[0].pixels.data(), images[0].pixels.size() * sizeof(float));
        return out;
    }

    /** Views by name, as (N, 2, 3) (dir, up), or none: the settings' own (--sweep, --views,
     *  else --view/--dir/--up), as fvr-render --out renders them. */
    py::array_t<float> renderMany(const py::object& views, const Args& extra) {
        const cli::Options o = options(extra);
        const std::vector<core::ViewFrame> frames = viewList(o, views);
        const core::ImageGeometry g = cli::imageGeometry(o, *m_volume.volume);
        std::vector<core::RenderParams> params;
        for (const auto& v : frames) params.push_back(cli::renderParams(o, v, g));
        if (!params.empty()) core::validateRenderParams(params[0]);
        auto out = imageStack(params.size(), g.rows(), g.cols());
        float* dst = out.mutable_data();
        const std::size_t pixels = std::size_t(g.rows()) * std::size_t(g.cols());
        py::gil_scoped_release release;
        std::lock_guard lock(m_mutex);
        const std::size_t width = std::size_t(m_batch->width());
        for (std::size_t first = 0; first < params.size(); first += width) {
            const std::vector<core::RenderParams> batch(
                params.begin() + std::ptrdiff_t(first),
                params.begin() + std::ptrdiff_t(std::min(params.size(), first + width)));
            const auto images = m_batch->renderBatch(batch);
            for (std::size_t i = 0; i < images.size(); ++i)
                std::memcpy(dst + (first + i) * pixels, images[i].pixels.data(),
                            pixels * sizeof(float));
        }
        return out;
    }

    /** The views render_many(None) renders, as (N, 2, 3) (dir, up). */
    py::array_t<double> views(const Args& extra) {
        const auto frames = viewList(options(extra), py::none());
        py::array_t<double> out({py::ssize_t(frames.size()), py::ssize_t(2), py::ssize_t(3)});
        auto w = out.mutable_unchecked<3>();
        for (std::size_t i = 0; i < frames.size(); ++i)
            for (int k = 0; k < 3; ++k) {
                w(py::ssize_t(i), 0, k) = frames[i].d[k];
                w(py::ssize_t(i), 1, k) = frames[i].u[k];
            }
        return out;
    }

    /** The "settings" object of fvr-render's sidecar for these settings, as JSON text. */
    std::string settingsJson(const Args& extra) const {
        const cli::Options o = options(extra);
        const core::ImageGeometry g = cli::imageGeometry(o, *m_volume.volume);
        return cli::jsonText(
            cli::settingsJson(cli::RunFacts{o, *m_spectrum, g.pixelSize, m_batch->width(), "cpu"}));
    }

    /** Cone-beam views (core::ConeProjector, made once per ray model and step and kept): an
     *  (n, H, W) stack of line integrals, every camera checked against the volume first. */
    py::array_t<float> renderCone(const std::vector<core::ConeCamera>& cameras,
                                  const std::string& model, double step) {
        refuseParallelOnlySettings();
        core::ConeProjectorOptions po;
        po.model = core::parseRayModel(model);
        po.stepFraction = step;
        po.mapping = m_options.settings.values; // mu for Hounsfield data, as the parallel views
        po.threads = m_options.threads;
        // pixel_aperture: the pixel's area, n x n rays averaged (fvr-render's default n).
        po.pixelSubsamples = m_options.settings.pixelAperture ? m_options.cone.pixelSubsamples : 1;
        if (po.model == core::RayModel::Box && step != 0.0)
            throw core::SettingsError("step: not with model box (exact path lengths, no step)");
        if (cameras.empty()) throw core::SettingsError("cameras: expected at least one camera");
        const int w = cameras[0].width, h = cameras[0].height;
        for (std::size_t i = 0; i < cameras.size(); ++i) {
            if (cameras[i].width != w || cameras[i].height != h)
                throw core::SettingsError(
                    "cameras: one stack needs one detector size: camera 0 has " + sizeText(w, h) +
                    ", camera " + std::to_string(i) + " " +
                    sizeText(cameras[i].width, cameras[i].height));
            try {
                core::validateConeView(cameras[i], *m_volume.volume);
            } catch (const core::SettingsError& e) {
                if (cameras.size() == 1) throw;
                throw core::SettingsError("camera " + std::to_string(i) + ": " + e.what());
            }
        }
        auto out =
            py::array_t<float>({py::ssize_t(cameras.size()), py::ssize_t(h), py::ssize_t(w)});
        float* dst = out.mutable_data();
        const std::size_t pixels = std::size_t(w) * std::size_t(h);
        py::gil_scoped_release release;
        std::lock_guard lock(m_coneMutex);
        core::ConeProjector& projector = coneProjector(po);
        for (std::size_t i = 0; i < cameras.size(); ++i) {
            const core::DetectorImage img = projector.project(cameras[i]);
            std::memcpy(dst + i * pixels, img.pixels.data(), pixels * sizeof(float));
        }
        return out;
    }

    const PyVolume& volume() const { return m_volume; }
    const Args& args() const { return m_args; }

private:
    static std::string sizeText(int w, int h) {
        return std::to_string(w) + "x" + std::to_string(h);
    }

    /** The renderer's settings that change a parallel image but have no cone-beam meaning (the
     *  ray caster would silently ignore them): refused, as fvr-render --geometry cone does. */
    void refuseParallelOnlySettings() const {
        const core::RenderSettings& s = m_options.settings;
        const core::RenderSettings d;
        auto refuse = [](const std::string& what, const std::string& why) {
            throw core::SettingsError(what + ": not with a cone-beam camera (" + why + ")");
        };
        if (s.depthCue != d.depthCue) refuse("depth_cue", "a Fourier rendering setting");
        if (s.filter.sharpenAmount != d.filter.sharpenAmount)
            refuse("sharpen", "a Fourier rendering setting");
        if (s.filter.bandLimitLpMm != d.filter.bandLimitLpMm)
            refuse("band_limit", "a Fourier rendering setting");
    }

    /** The projector of these options, made on first use (the value mapping and the empty-block
     *  map once per model, step and rays per pixel). Called with m_coneMutex held. */
    core::ConeProjector& coneProjector(const core::ConeProjectorOptions& po) {
        const auto key =
            std::make_tuple(int(po.model), po.stepFraction, int(po.mapping), po.pixelSubsamples);
        auto it = m_cone.find(key);
        if (it == m_cone.end())
            it = m_cone.emplace(key, std::make_unique<core::ConeProjector>(*m_volume.volume, po))
                     .first;
        return *it->second;
    }

    /** The renderer's settings with the call's: a view of the call replaces the renderer's own
     *  (--dir or --up drop its --view; --view drops its --dir and --up: fvr-render refuses
     *  --view with either). */
    cli::Options options(const Args& extra) const {
        auto given = [&](const char* name) {
            return std::find(extra.begin(), extra.end(), name) != extra.end();
        };
        std::vector<std::string> dropped;
        if (given("--dir") || given("--up")) dropped.push_back("--view");
        if (given("--view")) dropped.insert(dropped.end(), {"--dir", "--up"});
        Args all;
        for (std::size_t i = 0; i < m_args.size(); ++i) {
            if (std::find(dropped.begin(), dropped.end(), m_args[i]) != dropped.end()) {
                ++i; // and its value
                continue;
            }
            all.push_back(m_args[i]);
        }
        all.insert(all.end(), extra.begin(), extra.end());
        cli::Options o = rendererSettings(all);
        o.settings = o.settings.forVolume(*m_volume.volume);
        return o;
    }

    std::vector<core::ViewFrame> viewList(const cli::Options& o, const py::object& views) const {
        const core::Volume& vol = *m_volume.volume;
        if (views.is_none()) {
            const auto fileViews = o.viewsFile.empty() ? std::vector<core::ViewFrame>{}
                                                       : cli::readViewsFile(o.viewsFile);
            return cli::outputViews(o, vol, cli::baseView(o, vol), fileViews);
        }
        if (py::isinstance<py::str>(views))
            throw core::SettingsError("views: expected a list of view names, not one string");
        if (py::isinstance<py::sequence>(views) && py::len(views) > 0 &&
            py::isinstance<py::str>(views[py::int_(0)])) {
            std::vector<core::ViewFrame> frames;
            for (const py::handle name : views) {
                if (!py::isinstance<py::str>(name)) // was pybind11's "Unable to cast"
                    throw core::SettingsError("views: expected view names only, found " +
                                              py::repr(name).cast<std::string>() + " among them");
                frames.push_back(
                    core::patientViewFrame(vol, core::parsePatientView(name.cast<std::string>())));
            }
            return frames;
        }
        return viewsFromArray(views);
    }

    PyVolume m_volume;
    Args m_args;
    cli::Options m_options;
    std::shared_ptr<const core::Spectrum> m_spectrum;
    std::unique_ptr<core::CpuBatchRenderer> m_batch;
    std::mutex m_mutex;
    /** The cone-beam projectors by (model, step, value mapping, rays per pixel), and their own lock
     * (a cone view and a parallel view may render at once). */
    std::map<std::tuple<int, double, int, int>, std::unique_ptr<core::ConeProjector>> m_cone;
    std::mutex m_coneMutex;
};

/** Beer-Lambert: the transmitted intensity of line integrals (fvr-render --beer-lambert's rule:
 *  --energy, --mu-water, --exposure resolved by its checks). */
py::array_t<float> transmission(py::array_t<float, py::array::c_style | py::array::forcecast> img,
                                const Args& args) {
    const cli::Options o = cli::parseSettings(args);
    std::vector<float> pixels(img.data(), img.data() + img.size());
    core::applyTransmission(pixels, o.transmission);
    py::array_t<float> out(std::vector<py::ssize_t>(img.shape(), img.shape() + img.ndim()));
    std::memcpy(out.mutable_data(), pixels.data(), pixels.size() * sizeof(float));
    return out;
}

/** The film look of line integrals: brightness in [0, 1] through core::filmWindow (the window
 *  of fvr-render's Beer-Lambert PNGs and the workstation's views). */
py::array_t<float> film(py::array_t<float, py::array::c_style | py::array::forcecast> img,
                        const Args& args, bool invert) {
    const cli::Options o = cli::parseSettings(args);
    const std::vector<float> pixels(img.data(), img.data() + img.size());
    const core::DisplayWindow w = core::filmWindow(pixels, o.transmission, invert);
    py::array_t<float> out(std::vector<py::ssize_t>(img.shape(), img.shape() + img.ndim()));
    float* dst = out.mutable_data();
    for (std::size_t i = 0; i < pixels.size(); ++i) dst[i] = float(w.map(pixels[i]));
    return out;
}

/** fvr-render ARGS in this process (the dataset's tasks): its exit status; errors raise. */
int runCli(const Args& args) {
    cli::refuseNulArguments(args); // argv below are C strings
    std::vector<std::string> argv{"fvr-render"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> ptrs;
    for (auto& a : argv) ptrs.push_back(a.data());
    py::gil_scoped_release release;
    const auto o = cli::parseOptions(int(ptrs.size()), ptrs.data());
    return o ? cli::run(*o) : 0;
}

/** A camera from its parts, checked (core::ConeCamera::validate). */
core::ConeCamera makeCamera(const core::Vec3& source, const core::Vec3& centre, const core::Vec3& u,
                            const core::Vec3& v, int width, int height, double pitchU,
                            double pitchV, double du, double dv) {
    return core::coneCamera(source, centre, u, v, width, height, pitchU, pitchV, {du, dv});
}

/** A C-arm's camera (core::cArmCamera: DICOM's positioner angles, SID, SOD, isocentre). */
core::ConeCamera cArm(double primary, double secondary, double sid, double sod,
                      const core::Vec3& isocentre, int width, int height, double pitchU,
                      double pitchV, double du, double dv) {
    core::CArm arm;
    arm.primaryDeg = primary;
    arm.secondaryDeg = secondary;
    arm.sid = sid;
    arm.sod = sod;
    arm.isocentre = isocentre;
    return core::cArmCamera(arm, width, height, pitchU, pitchV, {du, dv});
}

/** P as a (3, 4) array. */
py::array_t<double> cameraMatrix(const core::ConeCamera& c) {
    const core::ProjectionMatrix p = c.matrix();
    py::array_t<double> out({py::ssize_t(3), py::ssize_t(4)});
    auto w = out.mutable_unchecked<2>();
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k) w(r, k) = p.rows[r][k];
    return out;
}

/** (N, 3) LPS points to (N, 3): column, row and depth w (mm along the detector normal from the
 *  source, > 0 in front of it). */
py::array_t<double> cameraProject(
    const core::ConeCamera& c, py::array_t<double, py::array::c_style | py::array::forcecast> x) {
    if (x.ndim() != 2 || x.shape(1) != 3)
        throw core::SettingsError("points: expected an (N, 3) array of LPS points in mm");
    const core::ProjectionMatrix p = c.matrix();
    py::array_t<double> out({x.shape(0), py::ssize_t(3)});
    auto r = x.unchecked<2>();
    auto w = out.mutable_unchecked<2>();
    for (py::ssize_t i = 0; i < x.shape(0); ++i) {
        const glm::dvec3 q = p.apply({r(i, 0), r(i, 1), r(i, 2)});
        for (int k = 0; k < 3; ++k) w(i, k) = q[k];
    }
    return out;
}

/** The camera of frame `frame` of a DICOM X-ray (core::readXrayGeometry), about the file's
 *  isocentre where it states one, else `isocentre` (SettingsError where neither is), with the
 *  reader's warnings and where the isocentre came from: (camera, warnings, "file"|"given"). */
py::tuple xrayCamera(const std::string& path, long frame,
                     const std::optional<core::Vec3>& isocentre) {
    const core::XrayGeometry g = core::readXrayGeometry(path, false);
    const std::size_t n = g.frameCount(); // C-arms, or an RT Image's beams
    if (frame < 0 || std::size_t(frame) >= n)
        throw core::SettingsError("frame: " + std::to_string(frame) + " asked for, " + path +
                                  " has " + std::to_string(n) + " frame" +
                                  (n == 1 ? " (0)" : "s (0.." + std::to_string(n - 1) + ")"));
    if (!g.isocentreStated && !isocentre)
        throw core::SettingsError("isocenter: " + path +
                                  " states no isocentre (no X-ray does, but a DRR fvr wrote): "
                                  "give the isocentre (x, y, z in LPS mm), or a volume whose "
                                  "centre it is");
    const glm::dvec3 iso = isocentre ? *isocentre : glm::dvec3(0.0);
    return py::make_tuple(g.camera(std::size_t(frame), iso), g.warnings,
                          g.isocentreStated ? "file" : "given");
}

/** A DICOM X-ray's pixels (core::readXrayGeometry): float32 (H, W), or (n, H, W) for several
 *  frames, and the reader's warnings. */
py::tuple xrayPixels(const std::string& path) {
    const core::XrayGeometry g = core::readXrayGeometry(path, true);
    const auto n = py::ssize_t(g.frameCount()), h = py::ssize_t(g.height), w = py::ssize_t(g.width);
    py::array_t<float> out = n == 1 ? py::array_t<float>({h, w}) : py::array_t<float>({n, h, w});
    if (g.pixels.size() != std::size_t(n * h * w))
        throw core::LoadError(path + ": expected " + std::to_string(n * h * w) +
                              " pixel values, read " + std::to_string(g.pixels.size()));
    std::memcpy(out.mutable_data(), g.pixels.data(), g.pixels.size() * sizeof(float));
    return py::make_tuple(out, g.warnings);
}

void bindCamera(py::module_& m) {
    using core::ConeCamera;
    py::class_<ConeCamera>(m, "Camera")
        .def(py::init(&makeCamera), py::arg("source"), py::arg("detector_centre"), py::arg("u"),
             py::arg("v"), py::arg("width"), py::arg("height"), py::arg("pitch_u"),
             py::arg("pitch_v"), py::arg("du"), py::arg("dv"))
        .def_static("carm", &cArm, py::arg("primary"), py::arg("secondary"), py::arg("sid"),
                    py::arg("sod"), py::arg("isocentre"), py::arg("width"), py::arg("height"),
                    py::arg("pitch_u"), py::arg("pitch_v"), py::arg("du"), py::arg("dv"))
        .def_static(
            "from_matrix",
            [](py::array_t<double, py::array::c_style | py::array::forcecast> p, int width,
               int height, double pitchU, double pitchV) {
                if (p.ndim() != 2 || p.shape(0) != 3 || p.shape(1) != 4)
                    throw core::SettingsError("matrix: expected a (3, 4) array");
                auto r = p.unchecked<2>();
                core::ProjectionMatrix matrix;
                for (int i = 0; i < 3; ++i)
                    matrix.rows[i] = glm::dvec4(r(i, 0), r(i, 1), r(i, 2), r(i, 3));
                return core::cameraFromMatrix(matrix, width, height, pitchU, pitchV);
            },
            py::arg("matrix"), py::arg("width"), py::arg("height"), py::arg("pitch_u"),
            py::arg("pitch_v"))
        .def_static("from_dicom", &xrayCamera, py::arg("path"), py::arg("frame"),
                    py::arg("isocentre"))
        .def_static("read_matrix_file",
                    [](const std::string& path) { return core::readProjectionMatrixFile(path); })
        .def_property_readonly("source", [](const ConeCamera& c) { return c.source; })
        .def_property_readonly("detector_centre",
                               [](const ConeCamera& c) { return c.detectorCentre; })
        .def_property_readonly("u", [](const ConeCamera& c) { return c.u; })
        .def_property_readonly("v", [](const ConeCamera& c) { return c.v; })
        .def_readonly("width", &ConeCamera::width)
        .def_readonly("height", &ConeCamera::height)
        .def_readonly("pitch_u", &ConeCamera::pitchU)
        .def_readonly("pitch_v", &ConeCamera::pitchV)
        .def_property_readonly("principal_point",
                               [](const ConeCamera& c) {
                                   return py::make_tuple(c.principalOffset.x, c.principalOffset.y);
                               })
        .def_property_readonly("sid", &ConeCamera::sourceToDetector)
        .def("pixel_centre",
             [](const ConeCamera& c, double col, double row) { return c.pixelCentre(col, row); })
        .def("matrix", &cameraMatrix)
        .def("project", &cameraProject, py::arg("points"))
        .def("flat_field", [](const ConeCamera& c) {
            c.validate();
            const std::vector<float> f = core::detectorFlatField(c);
            py::array_t<float> out({py::ssize_t(c.height), py::ssize_t(c.width)});
            std::memcpy(out.mutable_data(), f.data(), f.size() * sizeof(float));
            return out;
        });
    m.def("read_xray", &xrayPixels, py::arg("path"));
    m.def("volume_centre", [](const PyVolume& v) { return core::volumeCentre(*v.volume); });
    m.def("framing_pitch", [](const PyVolume& v, double sid, double sod, int width, int height) {
        return core::framingPitch(*v.volume, sid, sod, width, height);
    });
}

void bindVolume(py::module_& m) {
    py::class_<PyVolume>(m, "Volume")
        .def(py::init(&volumeFromArray), py::arg("array"), py::arg("spacing"), py::arg("origin"),
             py::arg("direction"), py::arg("units"), py::arg("name"))
        .def_property_readonly("shape",
                               [](const PyVolume& v) {
                                   const auto& d = v.volume->dims;
                                   return py::make_tuple(d[2], d[1], d[0]);
                               })
        .def_property_readonly("spacing", [](const PyVolume& v) { return v.volume->spacing; })
        .def_property_readonly("origin", [](const PyVolume& v) { return v.volume->origin; })
        .def_property_readonly("direction", [](const PyVolume& v) { return v.volume->direction; })
        .def_property_readonly("units",
                               [](const PyVolume& v) { return core::unitsName(v.volume->units); })
        .def_property_readonly("name", [](const PyVolume& v) { return v.volume->name; })
        .def_property_readonly("orientation_stated",
                               [](const PyVolume& v) { return v.volume->orientationStated; })
        .def_readonly("warnings", &PyVolume::warnings)
        .def_property_readonly("array", &volumeArray)
        .def_property_readonly("info_json", [](const PyVolume& v) {
            return cli::jsonText(cli::volumeInfoJson(*v.volume));
        });
}

void bindRenderer(py::module_& m) {
    py::class_<PyRenderer>(m, "Renderer")
        .def(py::init<PyVolume, Args, py::object>(), py::arg("volume"), py::arg("args"),
             py::arg("progress"))
        .def("render", &PyRenderer::render, py::arg("args"))
        .def("render_many", &PyRenderer::renderMany, py::arg("views"), py::arg("args"))
        .def("views", &PyRenderer::views, py::arg("args"))
        .def("settings_json", &PyRenderer::settingsJson, py::arg("args"))
        .def("render_cone", &PyRenderer::renderCone, py::arg("cameras"), py::arg("model"),
             py::arg("step"))
        .def_property_readonly("volume", &PyRenderer::volume)
        .def_property_readonly("args", &PyRenderer::args);
}

// ---- 2D/3D registration ------------------------------------------------------------------------

using FloatImage = py::array_t<float, py::array::c_style | py::array::forcecast>;
using ByteImage = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

/** The views: one (H, W) image per camera (its size), masks none or one per view. */
std::vector<core::RegistrationView> registrationViews(const std::vector<FloatImage>& images,
                                                      const std::vector<core::ConeCamera>& cameras,
                                                      const std::vector<ByteImage>& masks) {
    if (images.size() != cameras.size() || images.empty())
        throw core::SettingsError("images, cameras: one image per camera, at least one (found " +
                                  std::to_string(images.size()) + " images, " +
                                  std::to_string(cameras.size()) + " cameras)");
    if (!masks.empty() && masks.size() != images.size())
        throw core::SettingsError("masks: one per image or none");
    std::vector<core::RegistrationView> views;
    for (std::size_t i = 0; i < images.size(); ++i) {
        const FloatImage& a = images[i];
        const core::ConeCamera& c = cameras[i];
        if (a.ndim() != 2 || a.shape(0) != c.height || a.shape(1) != c.width)
            throw core::SettingsError("images[" + std::to_string(i) + "]: expected (" +
                                      std::to_string(c.height) + ", " + std::to_string(c.width) +
                                      "), its camera's (H, W)");
        core::RegistrationView v{"view " + std::to_string(i + 1),
                                 c,
                                 std::vector<float>(a.data(), a.data() + a.size()),
                                 {}};
        if (!masks.empty()) {
            const ByteImage& m = masks[i];
            if (m.ndim() != 2 || m.shape(0) != c.height || m.shape(1) != c.width)
                throw core::SettingsError("masks[" + std::to_string(i) +
                                          "]: expected its image's "
                                          "shape");
            v.mask.assign(m.data(), m.data() + m.size());
        }
        views.push_back(std::move(v));
    }
    return views;
}

/** Levels as (pixels, voxel_mm, evaluations[, step_deg, step_mm]) tuples; none: the defaults. */
std::vector<core::RegistrationLevel> registrationLevels(const std::vector<std::vector<double>>& l) {
    if (l.empty()) return core::RegistrationOptions().levels;
    std::vector<core::RegistrationLevel> out;
    for (const auto& t : l) {
        if (t.size() != 3 && t.size() != 5)
            throw core::SettingsError(
                "levels: each (pixels, voxel_mm, evaluations[, step_deg, step_mm])");
        core::RegistrationLevel level{int(t[0]), t[1], int(t[2])};
        if (t.size() == 5) {
            level.stepDeg = t[3];
            level.stepMm = t[4];
        }
        out.push_back(level);
    }
    return out;
}

py::array_t<double> matrixArray(const glm::dmat4& T) {
    py::array_t<double> a({4, 4});
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) a.mutable_at(r, c) = T[c][r]; // GLM: column-major
    return a;
}

py::dict registrationDict(const core::RegistrationResult& r) {
    py::list stages;
    for (const core::StageReport& s : r.stages) {
        py::dict d;
        d["name"] = s.name;
        d["renderer"] = s.renderer;
        d["image_size"] = py::make_tuple(s.imageWidth, s.imageHeight);
        d["voxel_mm"] = s.voxelMm;
        d["evaluations"] = s.evaluations;
        d["drrs"] = s.drrs;
        d["seconds"] = s.seconds;
        d["similarity_before"] = s.similarityBefore;
        d["similarity_after"] = s.similarityAfter;
        stages.append(d);
    }
    py::dict d;
    d["pose"] = matrixArray(r.matrix);
    d["rotation_deg"] = r.pose.rotationDeg;
    d["translation_mm"] = r.pose.translationMm;
    d["centre"] = r.centre;
    d["similarity_before"] = r.similarityBefore;
    d["similarity_after"] = r.similarityAfter;
    d["history"] = r.history;
    d["stages"] = stages;
    d["evaluations"] = r.evaluations;
    d["drrs"] = r.drrs;
    d["seconds"] = r.seconds;
    return d;
}

/** core::registerPose with the GIL released; init: a 4x4 (row-major) or six parameters (rx, ry,
 *  rz deg, tx, ty, tz mm about the centre); progress(stage, evaluations, similarity) between
 *  evaluations, with the GIL. */
py::dict registerPose(
    const PyVolume& volume, const std::vector<FloatImage>& images,
    const std::vector<core::ConeCamera>& cameras,
    std::optional<py::array_t<double, py::array::c_style | py::array::forcecast>> initMatrix,
    std::vector<double> initParams, const std::string& similarity,
    const std::vector<std::vector<double>>& levels, std::optional<int> globalSamples,
    std::optional<glm::dvec3> centre, int threads, const std::vector<ByteImage>& masks,
    bool coverageMask, double detectorBlur, py::object progress) {
    const std::vector<core::RegistrationView> views = registrationViews(images, cameras, masks);
    core::RegistrationOptions o;
    o.similarity = core::parseSimilarity(similarity);
    o.levels = registrationLevels(levels);
    if (globalSamples) {
        if (*globalSamples < 0) throw core::SettingsError("global_samples: expected >= 0");
        o.globalSamples = *globalSamples;
    }
    o.centreSet = true;
    o.centre = centre ? *centre : core::volumeCentre(*volume.volume);
    o.projector.threads = threads;
    o.coverageMask = coverageMask;
    o.detectorBlurPixels = detectorBlur;
    core::Pose init;
    if (initMatrix) {
        const auto& m = *initMatrix;
        if (m.ndim() != 2 || m.shape(0) != 4 || m.shape(1) != 4)
            throw core::SettingsError("init: expected a 4x4 matrix");
        glm::dmat4 T(1.0);
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) T[c][r] = m.at(r, c);
        init = core::poseFromMatrix(T, o.centre);
    } else if (!initParams.empty()) {
        if (initParams.size() != 6)
            throw core::SettingsError("init: expected rx, ry, rz, tx, ty, tz (6 numbers)");
        init = core::Pose::fromParameters(initParams.data());
    }
    if (!progress.is_none()) {
        // Shared, so that copies of the callback made without the GIL never touch its count.
        auto fn = std::make_shared<py::object>(std::move(progress));
        o.progress = [fn](const core::RegistrationProgress& p) {
            py::gil_scoped_acquire gil;
            (*fn)(p.stage, p.evaluations, p.bestSimilarity);
        };
    }
    core::RegistrationResult r;
    {
        py::gil_scoped_release release;
        r = core::registerPose(*volume.volume, views, init, o);
    }
    return registrationDict(r);
}
} // namespace

PYBIND11_MODULE(_fvr, m) {
    m.doc() = "fvr's C++ core (fvr::core and fvr-render's rules); use the package fvr.";
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const core::SettingsError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        }
    });
    bindVolume(m);
    bindCamera(m);
    bindRenderer(m);
    m.def("load", &load, py::arg("path"), py::arg("args"));
    m.def("transmission", &transmission, py::arg("image"), py::arg("args"));
    m.def("film", &film, py::arg("image"), py::arg("args"), py::arg("invert"));
    m.def("run_cli", &runCli, py::arg("args"));
    m.def("register_pose", &registerPose, py::arg("volume"), py::arg("images"), py::arg("cameras"),
          py::arg("init_matrix"), py::arg("init_params"), py::arg("similarity"), py::arg("levels"),
          py::arg("global_samples"), py::arg("centre"), py::arg("threads"), py::arg("masks"),
          py::arg("coverage_mask"), py::arg("detector_blur"), py::arg("progress"));
    m.def(
        "check_settings", [](const Args& args) { cli::parseSettings(args); }, py::arg("args"),
        "Reads fvr-render settings as fvr-render does: ValueError with its message, else None.");
}
