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

Bad settings raise ValueError carrying fvr-render's message (naming the option); other
failures (unreadable files...) raise RuntimeError. The GIL is released while C++ works.
"""
from __future__ import annotations

import json
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from . import _fvr

__all__ = ["Volume", "Renderer", "load", "transmission", "film", "option_args", "run_cli"]

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
        if isinstance(value, (tuple, list, np.ndarray)):
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

    def render(self, view: Optional[str] = None, dir=None, up=None, size: Optional[int] = None,
               pixel_size: Optional[float] = None) -> np.ndarray:
        """One projection (size, size) float32, row 0 at the top: the view by name (AP, PA,
        LEFT, RIGHT, HEAD, FEET) or by ``dir`` and ``up`` (volume frame), else the settings'
        view. ``size`` a power of two 128..2048 (default 512); ``pixel_size`` in mm (default:
        the volume's diagonal / size)."""
        return self._r.render(option_args(dict(view=view, dir=dir, up=up, size=size,
                                               pixel_size=pixel_size)))

    def render_many(self, views=None, size: Optional[int] = None,
                    pixel_size: Optional[float] = None) -> np.ndarray:
        """Projections (N, size, size) float32 of ``views``: names, or an (N, 2, 3) array of
        (dir, up); None: the settings' own views (``sweep=N`` about the head-feet axis, a
        ``views`` file, else the view), as ``fvr-render --out X.npy`` renders them. One view
        per CPU thread."""
        return self._r.render_many(views, option_args(dict(size=size, pixel_size=pixel_size)))

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
