"""topocal from Python: calibrate cone (null-screen) corneal topographers, measure eyes through them, read their
records and the fleet database (docs/python.md).

Units: mm, degrees, diopters (D), micrometres (um) where a name says so; pixels only for image positions (OpenCV's
convention). Images are 2-D uint8 or uint16 NumPy arrays, read in place. The numbers are the CLI's: the same library
calls, the same JSON documents (decoded by Python's json module).

Errors: InputError (a ValueError) for bad input, naming the file or key; Error (a RuntimeError) when a computation
fails; MeasurementRefused (an Error) when a capture cannot support a measurement, with `reasons` and `result`.
Nothing is printed.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from ._topocal import (  # noqa: F401  (re-exported)
    SPOT_DTYPE,
    SPOT_FLAGS,
    Config,
    Device,
    Error,
    FleetDb,
    InputError,
    MeasurementRefused,
    __commit__,
    __version__,
    calibrate_device,
    detect,
    export_calibration,
    get_num_threads,
    import_calibration,
    read_unit_record,
    set_num_threads,
)
from . import _topocal

PathLike = Union[str, os.PathLike]

__all__ = [
    "Calibration", "Config", "Device", "Error", "FleetDb", "InputError", "Map", "Measurement", "MeasurementRefused",
    "SPOT_DTYPE", "SPOT_FLAGS", "__commit__", "__version__", "calibrate", "calibrate_device", "detect",
    "export_calibration", "get_num_threads", "import_calibration",
    "read_unit_record", "reconstruct", "set_num_threads",
]


@dataclass(frozen=True)
class Map:
    """A map on a Cartesian grid, as the CLI's --maps CSV holds it: values[j, i] at (x_mm[i], y_mm[j]); NaN where
    there are no data."""
    values: np.ndarray
    x_mm: np.ndarray
    y_mm: np.ndarray
    unit: str
    title: str

    def extent(self) -> Tuple[float, float, float, float]:
        """(left, right, bottom, top) in mm, for matplotlib's imshow(..., origin="lower", extent=...)."""
        return (float(self.x_mm[0]), float(self.x_mm[-1]), float(self.y_mm[0]), float(self.y_mm[-1]))


@dataclass(frozen=True)
class Measurement:
    """A cornea measured by reconstruct().

    result: the document `topocal reconstruct --json` writes (surface_fit, clinical, adequacy, capture, ...).
    maps: "axial_power" and "tangential_power" (D), "elevation" (um above the best-fit sphere) as Map.
    polar: the exact power maps: axial_D and tangential_D (meridians x radii), rho_mm, theta_deg.
    """
    result: Dict[str, Any]
    maps: Dict[str, Map]
    polar: Dict[str, np.ndarray] = field(repr=False)

    @property
    def surface_fit(self) -> Dict[str, Any]:
        return self.result["surface_fit"]

    @property
    def clinical(self) -> Dict[str, Any]:
        return self.result["clinical"]


def reconstruct(config: Union[Config, PathLike], device: Union[Device, PathLike, None] = None,
                image: Optional[np.ndarray] = None, spots: Optional[np.ndarray] = None, estimator: str = "psf",
                truth: bool = False, eye: str = "", uncertainty: int = 0, seed: int = 1) -> Measurement:
    """Measure a cornea, as `topocal reconstruct` does.

    Give `image` (a raw sensor image, 2-D uint8/uint16, with the calibrated `device`), or `spots` (a structured
    array with ring, index, x_mm, y_mm: undistorted detection-plane mm, e.g. from detect() of an undistorted
    image; measured through `device` when given, else through the configuration's design). From an image, every
    spot is checked against the surface the others give and the measurement is judged: MeasurementRefused (with
    its reasons) when the capture cannot support it. truth=True compares with the configuration's cornea.
    eye: "OD" or "OS" (recorded in result["eye"], as `reconstruct --eye`).
    The configuration's surface model defaults to "auto" (the spline joins where the polynomial does not fit).
    From an image, every number carries its U (k = 2) as `reconstruct --device` reports it: result["uncertainty"]
    (per quantity: value, expanded, its sources) and polar["axial_expanded_D"] (U of the axial map at each sample);
    the device's part by linear propagation, or by `uncertainty` seeded Monte Carlo draws (`--uncertainty N`).
    """
    out = _topocal._reconstruct(config, device=device, image=image, spots=spots, estimator=estimator, truth=truth,
                                eye=eye, uncertainty=uncertainty, seed=seed)
    maps = dict(out["maps"])
    polar = maps.pop("polar")
    return Measurement(result=out["result"], maps={name: Map(**m) for name, m in maps.items()}, polar=polar)


@dataclass(frozen=True)
class Calibration:
    """A camera calibration by calibrate().

    report: the document `topocal calibrate --json` writes (rms_px, camera_matrix, dist_coeffs, stddev, ...).
    yaml: the calibration file's text (OpenCV-readable; every --calibration of the CLI reads it).
    skipped: (view, reason) for every view not used.
    """
    report: Dict[str, Any]
    yaml: str
    skipped: List[Tuple[str, str]]

    @property
    def camera_matrix(self) -> np.ndarray:
        return np.asarray(self.report["camera_matrix"], dtype=np.float64).reshape(3, 3)

    @property
    def dist_coeffs(self) -> np.ndarray:
        return np.asarray(self.report["dist_coeffs"], dtype=np.float64)

    def save(self, path: PathLike) -> None:
        """Write the calibration file (YAML) atomically, as the CLI writes its outputs."""
        _topocal._write_file(path, self.yaml)


def calibrate(target: PathLike, images: Optional[Sequence[Union[np.ndarray, PathLike]]] = None,
              corners: Optional[Sequence[Tuple[np.ndarray, np.ndarray]]] = None,
              image_size: Optional[Tuple[int, int]] = None, model: str = "brown5", fix: Sequence[str] = (),
              fix_aspect: float = 0.0, board_warp: bool = False) -> Calibration:
    """Calibrate a camera from views of a target (its YAML description, Kalibr's keys), as `topocal calibrate`.

    Give `images` (grey uint8 arrays or image paths: the target is detected in each), or `corners`: per view
    (target_mm (N, 2|3), image_px (N, 2)) with `image_size` = (width_px, height_px). model: "brown5" or "seidel";
    fix: parameter names held (fx fy cx cy k1 k2 p1 p2 k3); fix_aspect: hold fx/fy at this ratio (0: free).
    Raises Error when the fit fails (too few views, degenerate), InputError for bad input.
    """
    out = _topocal._calibrate(os.fspath(target), images=None if images is None else list(images),
                              corners=None if corners is None else list(corners), image_size=image_size, model=model,
                              fix=list(fix), fix_aspect=fix_aspect, board_warp=board_warp)
    return Calibration(report=out["report"], yaml=out["yaml"], skipped=[tuple(s) for s in out["skipped"]])
