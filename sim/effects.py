"""Which camera effects a dataset render applies, and their parameters (each off by default; depth, poses and
times are never touched): rolling shutter and motion blur (:mod:`sim.motion.shutter`), vignetting, auto-exposure
drift (the virtual drone camera's model, :mod:`sim.drone.exposure`) and sensor noise (:mod:`sim.render.film`).

With every effect off, the images are the renderer's bytes, unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.drone.exposure import AUTO_EXPOSURE

VIGNETTING_MODELS = ("cos4",)


@dataclass(frozen=True)
class CameraEffects:
    """Which effects to apply and their parameters (module docstring); the defaults switch every effect off.

    ``line_delay_s``: rolling-shutter delay between rows (s); ``exposure_s``: motion-blur exposure time (s),
    sampled ``blur_samples`` times; ``full_well_e``/``read_noise_e``: sensor noise in electrons (0: off);
    ``vignetting``: ``"cos4"`` or polynomial coefficients ``(k1, k2, k3)``; ``auto_exposure``: the drift on.
    """

    line_delay_s: float = 0.0
    exposure_s: float = 0.0
    blur_samples: int = 8
    full_well_e: float = 0.0
    read_noise_e: float = 0.0
    vignetting: str | tuple[float, ...] | None = None
    auto_exposure: bool = False

    def __post_init__(self) -> None:
        for name in ("line_delay_s", "exposure_s", "full_well_e", "read_noise_e"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"camera effect {name} must be a finite number >= 0, got {value}")
        if self.blur_samples < 1:
            raise ValueError(f"camera effect blur_samples must be at least 1, got {self.blur_samples}")
        if self.read_noise_e and not self.full_well_e:
            raise ValueError("camera effect read_noise_e needs full_well_e (the electrons of a full-scale pixel)")
        if isinstance(self.vignetting, str) and self.vignetting not in VIGNETTING_MODELS:
            raise ValueError(f"vignetting must be one of {VIGNETTING_MODELS} or three numbers k1,k2,k3, "
                             f"got {self.vignetting!r}")
        if self.vignetting is not None and not isinstance(self.vignetting, str):
            coefficients = tuple(float(k) for k in self.vignetting)
            if len(coefficients) != 3 or not all(map(math.isfinite, coefficients)):
                raise ValueError(f"vignetting polynomial needs three finite numbers k1,k2,k3, got {self.vignetting}")
            object.__setattr__(self, "vignetting", coefficients)

    @property
    def in_time(self) -> bool:
        """Rolling shutter or motion blur is on (each needs the pose at any time)."""
        return self.line_delay_s > 0 or self.exposure_s > 0

    @property
    def enabled(self) -> bool:
        return self.in_time or self.full_well_e > 0 or self.vignetting is not None or self.auto_exposure

    def description(self) -> dict:
        """What ``dataset.json`` records: each effect that is on with its parameters (empty when all are off)."""
        described = {}
        if self.line_delay_s > 0:
            described["rolling_shutter"] = {"line_delay_s": self.line_delay_s,
                                            "row_time": "t + (row - (height - 1) / 2) * line_delay_s"}
        if self.exposure_s > 0:
            described["motion_blur"] = {"exposure_s": self.exposure_s, "samples": self.blur_samples,
                                        "average": "linear light"}
        if self.vignetting is not None:
            described["vignetting"] = ({"model": "cos4"} if self.vignetting == "cos4" else
                                       {"model": "1 + k1 r^2 + k2 r^4 + k3 r^6", "k": list(self.vignetting)})
        if self.auto_exposure:
            figures = ("exposure_metering", "exposure_lag_s", "exposure_noise_std", "white_balance_std")
            described["auto_exposure"] = {name: getattr(AUTO_EXPOSURE, name) for name in figures}
        if self.full_well_e > 0:
            described["sensor_noise"] = {"full_well_e": self.full_well_e, "read_noise_e": self.read_noise_e,
                                         "model": "Poisson shot noise + Gaussian read noise, electrons"}
        return described
