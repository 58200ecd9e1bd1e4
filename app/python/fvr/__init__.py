"""fvr: Fourier volume rendering of CT and MR volumes from Python (DRRs in bulk).

Thin bindings over the C++ core of FVR Workstation and fvr-render's own rules: every setting
is an fvr-render option by its name (``kernel="sinc4"`` is ``--kernel sinc4``,
``pixel_size=0.8`` is ``--pixel-size 0.8``, ``keep_negative=True`` is ``--keep-negative``),
checked by the same declarations, with the same defaults and messages; the images equal
fvr-render's ``.npy`` outputs bit for bit. Images are float32 numpy arrays, row 0 at the top.

    import fvr
    vol = fvr.load("study/")                  # DICOM folder/file, .mhd/.mha/.nii(.gz), phantom:...
    r = fvr.Renderer(vol, kernel="kaiser-bessel", oversampling=1.25, values="mu")
    img = r.render(view="AP", size=512)       # (512, 512) line integrals
    stack = r.render_many(["AP", "LEFT"], size=256)
    cam = r.camera(primary=30, secondary=15, sid=1000, sod=750, detector=(640, 480))
    drr = r.render(camera=cam)                # (480, 640) cone-beam line integrals (ray cast)
    res = fvr.register(vol, drr, cam, init={"rotation_deg": (2, 0, 0)})  # 2D/3D: res["pose"]

Bad settings raise ValueError carrying fvr-render's message (naming the option); other
failures (unreadable files...) raise RuntimeError. The GIL is released while C++ works.
"""
from __future__ import annotations

import json
import os
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from . import _fvr

__all__ = ["Volume", "Camera", "Renderer", "load", "read_xray", "transmission", "film",
           "option_args", "run_cli", "register"]

# Python names whose fvr-render option is spelled otherwise.
_ALIASES = {"energy_kev": "energy"}


def option_args(settings: dict) -> list:
    """fvr-render option arguments from keyword settings.

    ``{"kernel": "sinc4", "pixel_size": 0.5, "dir": (1, 0, 0), "keep_negative": True}`` gives
    ``["--kernel", "sinc4", "--pixel-size", "0.5", "--dir", "1.0,0.0,0.0", "--keep-negative"]``.
    None and False leave the option out (its default); numbers are written so that they read
    back to the same double.
    """
    args = []
    for key, value in settings.items():
        if value is None or value is False:
            continue
        name = "--" + _ALIASES.get(key, key).replace("_", "-")
        if value is True:
            args.append(name)
            continue
        if key == "size" and isinstance(value, (tuple, list, np.ndarray)):
            if len(value) != 2:
                raise ValueError(f"size: expected N or (W, H), found {value!r}")
            text = f"{int(value[0])}x{int(value[1])}"  # columns x rows, as --size WxH
        elif isinstance(value, (tuple, list, np.ndarray)):
            text = ",".join(repr(float(v)) for v in value)
        elif isinstance(value, (float, np.floating)):
            text = repr(float(value))
        elif isinstance(value, (int, np.integer)):
            text = str(int(value))
        else:
            text = str(value)
        args += [name, text]
    return args


class Volume:
    """A scalar volume: float32 voxels on a regular grid, in the patient (LPS) frame.

    ``Volume(array, spacing=(sx, sy, sz))`` takes a (z, y, x) array (converted to C-ordered
    float32 where it is not; the volume keeps one copy of its own). ``spacing`` (mm) and
    ``origin`` (mm) are in x, y, z order; ``direction[a]`` is the unit vector of index axis a;
    ``units`` is "unknown", "HU", "mu/mu_water" or "intensity".
    """

    def __init__(self, array, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0),
                 direction=((1, 0, 0), (0, 1, 0), (0, 0, 1)), units: str = "unknown",
                 name: str = "array"):
        if isinstance(array, _fvr.Volume):
            self._v = array
            return
        self._v = _fvr.Volume(array, tuple(map(float, spacing)), tuple(map(float, origin)),
                              [tuple(map(float, row)) for row in direction], units, name)

    shape = property(lambda self: self._v.shape, doc="(nz, ny, nx)")
    spacing = property(lambda self: tuple(self._v.spacing), doc="(sx, sy, sz) in mm")
    origin = property(lambda self: tuple(self._v.origin), doc="position of voxel (0, 0, 0), mm")
    direction = property(lambda self: tuple(map(tuple, self._v.direction)),
                         doc="unit vectors of the index axes (x, y, z) in the patient frame")
    units = property(lambda self: self._v.units, doc="what the values mean")
    name = property(lambda self: self._v.name, doc="the source's name")
    warnings = property(lambda self: list(self._v.warnings), doc="what the loader said")
    orientation_stated = property(lambda self: self._v.orientation_stated,
                                  doc="False where the direction is the identity by assumption")

    @property
    def array(self) -> np.ndarray:
        """The voxels as a read-only (z, y, x) float32 array (no copy)."""
        return self._v.array

    @property
    def info(self) -> dict:
        """fvr-render --info's facts (dims, spacing_mm, origin_mm, value_range...)."""
        return json.loads(self._v.info_json)

    def __repr__(self):
        return f"fvr.Volume({self.name!r}, shape={self.shape}, spacing={self.spacing}, units={self.units!r})"


def load(path: str, series: Optional[str] = None, **settings) -> Volume:
    """Opens a DICOM folder, DICOMDIR or file, a .mhd/.mha/.nii(.gz) volume or a phantom
    (``phantom:chest[:N]``, ``phantom:shepp-logan[:N]``) by the workstation's rule.

    ``series`` picks a DICOM folder's series by key or UID (default: the loadable one with most
    slices); raw files take ``raw_dims=(nx, ny, nz)``, ``raw_type=``... as fvr-render does.
    """
    return Volume(_fvr.load(str(path), option_args(dict(series=series, **settings))))


def _pair(value, what: str) -> tuple:
    """(a, b) from a number (a, a) or a pair."""
    if isinstance(value, (tuple, list, np.ndarray)):
        if len(value) != 2:
            raise ValueError(f"{what}: expected one number or two, found {len(value)}")
        return tuple(value)
    return (value, value)


def _point(value, what: str) -> tuple:
    if len(value) != 3:
        raise ValueError(f"{what}: expected (x, y, z) in LPS mm, found {len(value)} numbers")
    return tuple(map(float, value))


class Camera:
    """A cone-beam camera (core's ConeCamera), in patient LPS millimetres: a point source and a
    flat detector of ``width`` x ``height`` pixels of pitch ``pitch`` (pu, pv) mm, columns along
    the unit vector ``u`` and rows along ``v``. Pixel (col, row) lies at ``detector_centre +
    (col - (W-1)/2 + du) pu u + (row - (H-1)/2 + dv) pv v``, (du, dv) the ``principal_point``
    offset in pixels; pixel centres at integer 0-based (col, row). ``matrix`` is the 3x4 P with
    [w col, w row, w] = P [x, y, z, 1].

    ``Camera(source, detector_centre, u, v, detector=(W, H), pitch=(pu, pv))`` takes the parts;
    ``Camera.carm(...)`` a C-arm by DICOM's positioner angles. Bad geometry raises ValueError
    naming what is wrong (a size outside 16..4096, a pitch not > 0, u and v not orthonormal...).
    """

    def __init__(self, source, detector_centre, u, v, detector, pitch,
                 principal_point=(0.0, 0.0)):
        w, h = _pair(detector, "detector")
        pu, pv = _pair(pitch, "pitch")
        du, dv = _pair(principal_point, "principal_point")
        self._c = _fvr.Camera(_point(source, "source"), _point(detector_centre, "detector_centre"),
                              _point(u, "u"), _point(v, "v"), int(w), int(h), float(pu),
                              float(pv), float(du), float(dv))

    @classmethod
    def carm(cls, primary: float = 0.0, secondary: float = 0.0, sid: float = 1000.0,
             sod: float = 750.0, isocenter=None, detector=512, pitch=None,
             principal_point=(0.0, 0.0), volume: Optional[Volume] = None) -> "Camera":
        """A C-arm (DICOM PS3.3 C.8.7.5 positioner angles, degrees): ``primary`` LAO +, RAO -;
        ``secondary`` cranial +, caudal -; ``sid`` source to detector and ``sod`` source to
        isocentre (mm, 0 < SOD < SID). d = (sin a cos b, -cos a cos b, sin b) points from the
        isocentre to the detector; source = I - SOD d, detector centre = I + (SID - SOD) d,
        u = (cos a, sin a, 0), v = u x d: at 0/0 the source is posterior, columns run to the
        patient's left and rows to the feet.

        ``detector``: W x H pixels, (W, H) or one number for a square (16..4096 each).
        ``isocenter`` (LPS mm) and ``pitch`` (mm, one number or (pu, pv)) may be left None only
        with ``volume``: then the isocentre is the volume's centre and the pitch frames the
        volume's diagonal, magnified at the isocentre by SID/SOD, on the smaller of W and H (as
        fvr-render --geometry cone's defaults). ``principal_point``: the offset (du, dv) in
        pixels of the class's pixel formula (the isocentre then projects to ((W-1)/2 - du,
        (H-1)/2 - dv)). ``Renderer.camera(...)`` passes its own volume."""
        w, h = _pair(detector, "detector")
        if isocenter is None:
            if volume is None:
                raise ValueError("isocenter: give the isocentre (x, y, z in LPS mm), or a volume "
                                 "whose centre it is")
            isocenter = _fvr.volume_centre(volume._v)
        if pitch is None:
            if volume is None:
                raise ValueError("pitch: give the detector's pitch in mm, or a volume for the "
                                 "pitch that frames it")
            pitch = _fvr.framing_pitch(volume._v, float(sid), float(sod), int(w), int(h))
        pu, pv = _pair(pitch, "pitch")
        du, dv = _pair(principal_point, "principal_point")
        return cls._wrap(_fvr.Camera.carm(float(primary), float(secondary), float(sid),
                                          float(sod), _point(isocenter, "isocenter"), int(w),
                                          int(h), float(pu), float(pv), float(du), float(dv)))

    @classmethod
    def from_matrix(cls, matrix, detector, pitch) -> "Camera":
        """The camera of a 3x4 projection matrix P ([w col, w row, w] = P [x, y, z, 1], LPS mm,
        pixel centres at integer (col, row); any positive scale) on a ``detector`` of W x H
        pixels: P fixes the source, the detector's directions and the principal point, and
        the pitch (one number, or (pu, pv); pv may be None to take it from P) fixes the
        detector's distance. A singular or skewed P raises ValueError."""
        w, h = _pair(detector, "detector")
        if isinstance(pitch, (int, float)):
            pu, pv = float(pitch), 0.0
        else:
            pu, pv = float(pitch[0]), 0.0 if pitch[1] is None else float(pitch[1])
        return cls._wrap(_fvr.Camera.from_matrix(np.asarray(matrix, dtype=np.float64), int(w),
                                                 int(h), pu, pv))

    @classmethod
    def from_dicom(cls, path, frame: int = 0, isocenter=None,
                   volume: Optional[Volume] = None) -> "Camera":
        """The camera of frame ``frame`` (0-based) of a DICOM X-ray (XA, RF, DX, CR; single or
        multi-frame): its C-arm (PositionerPrimary/SecondaryAngle, per frame where stated),
        DistanceSourceToDetector and DistanceSourceToPatient, Rows x Columns and
        ImagerPixelSpacing, as fvr-render --geometry-from reads them; or of an RT Image (its
        treatment beam's IEC 61217 angles, RadiationMachineSAD, RTImageSID and imager, and its
        IsocenterPosition as the file's isocentre).

        The isocentre: the file's where it states one (a DRR that fvr wrote, with ``--out
        x.dcm``), else ``isocenter`` (LPS mm), else the centre of ``volume``; with none of
        them ValueError. Whatever the reader had to assume (a missing tag and the value taken)
        is in the returned camera's ``warnings`` (a list of str, empty when the file states
        everything), and ``isocenter_from`` says "file", "isocenter" or "volume". A file that
        cannot be read raises RuntimeError naming it."""
        given, source = None, None
        if isocenter is not None:
            given, source = _point(isocenter, "isocenter"), "isocenter"
        elif volume is not None:
            given, source = _fvr.volume_centre(volume._v), "volume"
        c, warnings, stated = _fvr.Camera.from_dicom(os.fspath(path), int(frame), given)
        camera = cls._wrap(c)
        camera.warnings = list(warnings)
        camera.isocenter_from = "file" if stated == "file" else source
        return camera

    @classmethod
    def read_matrix_file(cls, path) -> list:
        """The cameras of a projection-matrix file (fvr-render --projection-matrix's format:
        ``detector W H``, ``pitch PU [PV]``, then 3 rows of 4 numbers per view)."""
        return [cls._wrap(c) for c in _fvr.Camera.read_matrix_file(os.fspath(path))]

    #: What Camera.from_dicom had to assume (empty for a camera made otherwise).
    warnings: list = []
    #: Where Camera.from_dicom's isocentre came from ("file", "isocenter", "volume"), else None.
    isocenter_from: Optional[str] = None

    @classmethod
    def _wrap(cls, c) -> "Camera":
        camera = cls.__new__(cls)
        camera._c = c
        return camera

    source = property(lambda self: tuple(self._c.source), doc="the point source, LPS mm")
    detector_centre = property(lambda self: tuple(self._c.detector_centre),
                               doc="where the principal ray of a centred detector lands, LPS mm")
    u = property(lambda self: tuple(self._c.u), doc="unit vector along increasing columns")
    v = property(lambda self: tuple(self._c.v), doc="unit vector along increasing rows")
    width = property(lambda self: self._c.width, doc="W, columns")
    height = property(lambda self: self._c.height, doc="H, rows")
    pitch = property(lambda self: (self._c.pitch_u, self._c.pitch_v),
                     doc="(pu, pv): mm between column and between row centres")
    principal_point = property(lambda self: tuple(self._c.principal_point),
                               doc="the offset (du, dv) in pixels of the pixel formula above: "
                                   "the principal ray lands at ((W-1)/2 - du, (H-1)/2 - dv)")
    sid = property(lambda self: self._c.sid,
                   doc="source to detector plane along its normal, mm")

    @property
    def matrix(self) -> np.ndarray:
        """P, (3, 4) float64: [w col, w row, w] = P [x, y, z, 1] (x, y, z in LPS mm)."""
        return self._c.matrix()

    def project(self, points, depth: bool = False) -> np.ndarray:
        """(col, row) of LPS points (mm): (N, 3) gives (N, 2), one point (3,) gives (2,);
        ``depth=True`` adds w, the depth along the detector normal from the source (mm, > 0
        in front of it)."""
        p = np.asarray(points, dtype=np.float64)
        one = p.ndim == 1
        q = self._c.project(p.reshape(1, -1) if one else p)
        q = q if depth else q[:, :2]
        return q[0] if one else q

    def pixel_centre(self, col: float, row: float) -> tuple:
        """Where the centre of pixel (col, row) lies, LPS mm (fractional indices allowed)."""
        return tuple(self._c.pixel_centre(float(col), float(row)))

    def flat_field(self) -> np.ndarray:
        """(H, W) float32: a real flat panel's open-beam response relative to the pixel under
        the source's foot, inverse square times obliquity, (SID / r)^3 with r the distance from
        the source to the pixel's centre. It multiplies transmitted intensities
        (``r.transmission(img) * cam.flat_field()``), never line integrals; no render applies
        it by itself."""
        return self._c.flat_field()

    def __reduce__(self):  # pickles (Dask) by its parts
        return (Camera, (self.source, self.detector_centre, self.u, self.v,
                         (self.width, self.height), self.pitch, self.principal_point))

    def __repr__(self):
        return (f"fvr.Camera(source={self.source}, detector_centre={self.detector_centre}, "
                f"detector=({self.width}, {self.height}), pitch={self.pitch})")


def read_xray(path) -> np.ndarray:
    """The pixels of a DICOM X-ray (XA, RF, DX, CR) as float32: (H, W) for one frame, (n, H, W)
    for several; the real values (rescale or Modality LUT applied, MONOCHROME1 inverted so that
    larger is brighter), row 0 at the top, in the orientation of ``Camera.from_dicom``'s camera
    (an image stored mirrored is flipped to it, with a warning). For a DRR that fvr-render wrote
    as .dcm: its line integrals (or transmission) within the 16-bit quantisation of their range.
    A file that cannot be read raises RuntimeError naming it."""
    pixels, _ = _fvr.read_xray(os.fspath(path))
    return pixels


def _cameras(views) -> Optional[list]:
    """The cameras of ``views`` when it is a Camera or a sequence of them, else None."""
    if isinstance(views, Camera):
        return [views]
    if isinstance(views, (list, tuple)) and views and all(isinstance(c, Camera) for c in views):
        return list(views)
    if isinstance(views, (list, tuple)) and any(isinstance(c, Camera) for c in views):
        raise ValueError("views: expected cameras only, or view names, found a mix")
    return None


class Renderer:
    """A volume's spectrum, made once, and its projections (DRRs) on the CPU.

    Keyword settings are fvr-render's options, with fvr-render's defaults (core's
    RenderSettings: the AP view, mu for Hounsfield data, kaiser-bessel with gridding correction
    at 1.25x, the trilinear voxel model): ``preset`` ("default" or "paper": the paper's
    Table 1 setting), ``kernel`` (nearest, linear, bspline, catmull-rom, sinc4, kaiser-bessel),
    ``oversampling`` (1..2), ``values`` (raw, mu, mu-bone), ``voxel_model`` (trilinear, bspline,
    bandlimited), ``threads`` (0: all cores), and any other (``deapodize="on"``,
    ``depth_cue=0.3``, ``sweep=12``, ``axis=(0, 0, 1)``, ``view="AP"``, ``size=256``...).
    ``progress(fraction, stage)`` is called while the spectrum is made (an exception there
    stops it).
    """

    def __init__(self, volume: Volume, kernel: Optional[str] = None,
                 oversampling: Optional[float] = None, values: Optional[str] = None,
                 voxel_model: Optional[str] = None, threads: Optional[int] = None,
                 progress: Optional[Callable[[float, str], Any]] = None, **settings):
        args = option_args(dict(kernel=kernel, oversampling=oversampling, values=values,
                                voxel_model=voxel_model, threads=threads, **settings))
        self.volume = volume
        self._r = _fvr.Renderer(volume._v, args, progress)

    @property
    def args(self) -> list:
        """The fvr-render option arguments of the renderer's settings."""
        return list(self._r.args)

    def render(self, view: Optional[str] = None, dir=None, up=None, size=None,
               pixel_size: Optional[float] = None, camera: Optional[Camera] = None,
               model: Optional[str] = None, step: Optional[float] = None) -> np.ndarray:
        """One projection (H, W) float32, row 0 at the top: the view by name (AP, PA,
        LEFT, RIGHT, HEAD, FEET) or by ``dir`` and ``up`` (volume frame), else the settings'
        view. ``size`` N (square) or (W, H), each 16..4096 (default 512); ``pixel_size`` in mm
        (default: the volume's diagonal / min(W, H)). The volume's centre is at pixel
        (W // 2, H // 2).

        ``camera=`` (a Camera) renders a cone beam instead: (H, W) line integrals from the
        source to each pixel's centre, by CPU ray casting, in the parallel views' units (the
        renderer's ``values``: mm of water for mu). ``model``: "trilinear" (default, exact per
        cell), "box" (voxels as cubes, exact path lengths: plastimatch drr -i exact) or
        "bspline"; ``step``: the ray step as a fraction 0..4 of the smallest voxel spacing
        (trilinear: 0 = exact; bspline: 0 = 0.25; not for box). A renderer made with
        ``pixel_aperture=True`` averages 4 x 4 rays over each pixel (its area, as fvr-render
        --pixel-aperture). This module renders no polychromatic images: ``kvp`` is refused
        when the renderer is made (fvr.run_cli with --kvp runs fvr-render, which does)."""
        if camera is None:
            if model is not None or step is not None:
                raise ValueError("model, step: only with camera= (the cone-beam ray caster)")
            return self._r.render(option_args(dict(view=view, dir=dir, up=up, size=size,
                                                   pixel_size=pixel_size)))
        return self.render_many([camera], model=model, step=step,
                                **dict(view=view, dir=dir, up=up, size=size,
                                       pixel_size=pixel_size))[0]

    def render_many(self, views=None, size=None,
                    pixel_size: Optional[float] = None, model: Optional[str] = None,
                    step: Optional[float] = None, **parallel) -> np.ndarray:
        """Projections (N, H, W) float32 (``size`` as in render()) of ``views``: names, or an
        (N, 2, 3) array of (dir, up); None: the settings' own views (``sweep=N`` about the
        head-feet axis, a ``views`` file, else the view), as ``fvr-render --out X.npy`` renders
        them. One view per CPU thread.

        ``views`` a list of Cameras (one detector size): cone-beam views (N, H, W), as
        render(camera=) renders each (``model``, ``step``); the ray caster is made once per
        model and step and kept by the renderer."""
        cameras = _cameras(views)
        if cameras is None:
            if model is not None or step is not None:
                raise ValueError("model, step: only with cameras (the cone-beam ray caster)")
            if parallel:
                raise TypeError(f"render_many: unexpected arguments {sorted(parallel)}")
            return self._r.render_many(views, option_args(dict(size=size, pixel_size=pixel_size)))
        given = dict(size=size, pixel_size=pixel_size, **parallel)
        wrong = [k for k, v in given.items() if v is not None]
        if wrong:
            raise ValueError(f"{', '.join(wrong)}: not with a cone-beam camera (the camera "
                             f"gives the view, the detector's size and its pitch)")
        return self._r.render_cone([c._c for c in cameras], model or "trilinear",
                                   0.0 if step is None else float(step))

    def camera(self, **carm) -> Camera:
        """Camera.carm(...) about this renderer's volume: the isocentre defaults to its centre
        and the pitch to the one that frames it."""
        return Camera.carm(volume=self.volume, **carm)

    def views(self, **settings) -> np.ndarray:
        """The (N, 2, 3) (dir, up) views render_many(None) renders (e.g. ``sweep=36``)."""
        return self._r.views(option_args(settings))

    @property
    def settings(self) -> dict:
        """The "settings" record of fvr-render's JSON sidecar for these settings."""
        return json.loads(self._r.settings_json([]))

    def transmission(self, image: np.ndarray, energy_kev: Optional[float] = None,
                     mu_water: Optional[float] = None, exposure: Optional[float] = None) -> np.ndarray:
        """Beer-Lambert: exposure x exp(-mu_water x line integral), mu_water from ``energy_kev``
        (NIST XCOM, 20..150 keV) or ``mu_water`` (1/mm; default that of 70 keV, 0.01937). Needs
        ``values="mu"`` or ``"mu-bone"`` on Hounsfield data (ValueError otherwise: other data
        render their raw values), as fvr-render --beer-lambert."""
        if self.settings["values"] == "raw" and self.volume.units != "HU":
            raise ValueError(f"--beer-lambert: the values are not Hounsfield units "
                             f"({self.volume.units}): this renderer integrates the raw values, "
                             f"and a transmission needs attenuation")
        return _fvr.transmission(image, self._r.args + _beer(energy_kev, mu_water, exposure))


def _beer(energy_kev, mu_water, exposure) -> list:
    return option_args(dict(beer_lambert=True, energy_kev=energy_kev, mu_water=mu_water,
                            exposure=exposure))


def transmission(image: np.ndarray, energy_kev: Optional[float] = None,
                 mu_water: Optional[float] = None, exposure: Optional[float] = None) -> np.ndarray:
    """Beer-Lambert transmission of line integrals of mu values (see Renderer.transmission)."""
    return _fvr.transmission(image, ["--values", "mu"] + _beer(energy_kev, mu_water, exposure))


def film(image: np.ndarray, energy_kev: Optional[float] = None, mu_water: Optional[float] = None,
         exposure: Optional[float] = None, invert: bool = True) -> np.ndarray:
    """The film look of line integrals of mu values: brightness 0..1 through the automatic
    window of the log exposure (what fvr-render's Beer-Lambert PNGs and the workstation show);
    ``invert=True`` bone white, False the fluoroscopy look."""
    return _fvr.film(image, ["--values", "mu"] + _beer(energy_kev, mu_water, exposure), invert)


def run_cli(args: Sequence[str]) -> int:
    """Runs ``fvr-render ARGS`` in this process (GIL released): the same files, sidecar and
    messages (on stderr) as the program. Raises ValueError for bad settings, RuntimeError for
    other failures."""
    return _fvr.run_cli([str(a) for a in args])


def register(volume: Volume, images, cameras, init=None, similarity: str = "gradient-ncc",
             levels=None, global_samples: Optional[int] = None, centre=None, threads: int = 0, masks=None,
             coverage_mask: bool = True, detector_blur: float = 0.0,
             progress: Optional[Callable[[str, int, float], None]] = None) -> dict:
    """2D/3D registration: the rigid pose of ``volume`` (a CT) whose cone-beam DRRs best match
    ``images`` (one (H, W) array per camera, or an (n, H, W) stack: line integrals, larger = more
    attenuation; a raw radiograph's intensities first as -ln(I / I0)) seen by ``cameras`` (a
    Camera or a list: one view, or two for a biplane pair, registered jointly).

    The pose T maps a CT point X (LPS mm) to the same anatomy in the cameras' frame: the X-ray
    shows X at pixel P T X; the identity is the geometry as the cameras record it.
    T X = R (X - c) + c + t with R = Rz Ry Rx (degrees about the LPS x, y, z axes, x first), c the
    ``centre`` (default: the volume's centre), t in mm.

    ``init``: None (the identity), a 4x4 matrix (row-major), or a dict with ``rotation_deg`` and
    ``translation_mm`` (about ``centre``). ``similarity``: "gradient-ncc" (default) or "ncc".
    ``levels``: [(pixels, voxel_mm, evaluations[, step_deg, step_mm]), ...] coarse to fine
    (pixels: the images' larger side at that level, 0 full; voxel_mm: the CT's, 0 as it is);
    None: core's defaults. ``global_samples``: Halton poses of the global stage, at its own
    coarse level before the others (0: none; None: core's default, 200).
    ``masks``: None, or one uint8 (H, W) per image (non-zero = counted). ``coverage_mask``: leave
    out pixels whose rays leave the CT through its cut ends. ``detector_blur``: the images'
    detector blur (a Gaussian's sigma in pixels), given to the DRRs too. ``progress(stage, evaluations,
    similarity)`` is called as it goes.

    Returns a dict: ``pose`` (4x4 numpy, row-major), ``rotation_deg``, ``translation_mm``,
    ``centre``, ``similarity_before`` / ``similarity_after`` (full resolution, mean over the
    views), ``history`` (the best similarity after each evaluation), ``stages`` (name, renderer,
    image_size, voxel_mm, evaluations, drrs, seconds, similarity before/after), ``evaluations``,
    ``drrs``, ``seconds``. Bad input raises ValueError naming it."""
    cams = _cameras(cameras)
    if cams is None:
        raise ValueError("cameras: expected a Camera or a list of Cameras")
    if isinstance(images, np.ndarray) and images.ndim == 3:
        images = list(images)
    elif isinstance(images, np.ndarray):
        images = [images]
    images = [np.ascontiguousarray(a, dtype=np.float32) for a in images]
    if masks is not None:
        masks = [np.ascontiguousarray(m, dtype=np.uint8) for m in
                 (list(masks) if isinstance(masks, (list, tuple)) or np.ndim(masks) == 3
                  else [masks])]
    init_matrix, init_params = None, []
    if isinstance(init, dict):
        init_params = [float(x) for x in list(init.get("rotation_deg", (0, 0, 0))) +
                       list(init.get("translation_mm", (0, 0, 0)))]
    elif init is not None:
        init_matrix = np.asarray(init, dtype=np.float64)
    return _fvr.register_pose(volume._v, images, [c._c for c in cams], init_matrix, init_params,
                              similarity, [tuple(map(float, l)) for l in (levels or [])],
                              None if global_samples is None else int(global_samples),
                              None if centre is None else _point(centre, "centre"), int(threads),
                              masks or [], bool(coverage_mask), float(detector_blur),
                              progress)
