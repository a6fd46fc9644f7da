"""The paper's random sun, reproducible from ``(seed, frame index)``."""

from __future__ import annotations

from dataclasses import dataclass

from sim.sampling.seeds import SUN_STREAM, frame_rng


@dataclass(frozen=True)
class SunSample:
    """Sunlight for one frame.

    ``azimuth_deg`` clockwise from north, ``elevation_deg`` above the horizon (the direction
    *towards* the sun); ``intensity`` is the sun's strength in the paper's (Blender sun
    "Strength", irradiance) units. ``sweep_angle_deg`` is the paper's angle: the sun's angle
    from the horizon measured within a vertical plane, 90 = zenith, over 90 = past the zenith
    (the sun then stands on the opposite azimuth).
    """

    azimuth_deg: float
    elevation_deg: float
    intensity: float
    sweep_angle_deg: float


def random_sun(seed: int, index: int, sweep_range_deg=(30.0, 150.0), intensity_range=(5.0, 10.0)) -> SunSample:
    """The paper's sun: a sweep angle in [30, 150] deg in a random vertical plane, intensity in [5, 10].

    Physically: the sun stands at least 30 deg above the horizon (elevation uniform in
    [30, 90] deg), from any azimuth, with a brightness varying by a factor of two.
    """
    rng = frame_rng(seed, index, SUN_STREAM)
    sweep = rng.uniform(*sweep_range_deg)
    plane_azimuth = rng.uniform(0.0, 180.0)
    intensity = rng.uniform(*intensity_range)
    azimuth = plane_azimuth if sweep <= 90.0 else (plane_azimuth + 180.0) % 360.0
    return SunSample(azimuth, 90.0 - abs(sweep - 90.0), intensity, sweep)
