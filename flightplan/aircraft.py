"""Aircraft and camera profiles used to check and predict a mission (and later by the virtual drone and recon).

Numbers come from ``research/litchi.md`` section 4. Every profile lists the fields that could not be confirmed
in a primary source in ``unverified``; treat those as best estimates until measured on the real aircraft.
Angles are degrees, lengths metres (sensor sizes millimetres), times seconds, speeds metres per second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class CameraProfile:
    """A camera described by its native image size and diagonal field of view, and its lens calibration.

    The diagonal FOV is the one number DJI publishes; the horizontal/vertical FOVs and the focal length in
    pixels follow from it for a centred, distortion-free pinhole with square pixels. The lens calibration is
    what a DJI camera's factory calibration (XMP ``DewarpData``) adds: ``distortion`` OpenCV's radial-tangential
    ``(k1, k2, p1, p2, k3)`` on normalised coordinates, ``principal_point_offset_px`` the principal point's
    offset ``(dx, dy)`` from the image centre in native pixels. Zeros: an ideal lens.
    """

    name: str
    image_width_px: int
    image_height_px: int
    diagonal_fov_deg: float
    sensor_width_mm: float
    unverified: tuple[str, ...] = ()
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    principal_point_offset_px: tuple[float, float] = (0.0, 0.0)

    def focal_length_px(self, image_width_px: int | None = None) -> float:
        """Focal length in pixels for an image of ``image_width_px`` columns (default: the native width).

        Resizing keeps the field of view, so the focal length scales with the width.
        """
        native = 0.5 * math.hypot(self.image_width_px, self.image_height_px) / math.tan(
            math.radians(self.diagonal_fov_deg) / 2.0
        )
        width = self.image_width_px if image_width_px is None else image_width_px
        return native * width / self.image_width_px

    @property
    def horizontal_fov_deg(self) -> float:
        """Full field of view across the image width."""
        return math.degrees(2.0 * math.atan(0.5 * self.image_width_px / self.focal_length_px()))

    @property
    def vertical_fov_deg(self) -> float:
        """Full field of view across the image height."""
        return math.degrees(2.0 * math.atan(0.5 * self.image_height_px / self.focal_length_px()))

    def pinhole_intrinsics(self, image_width_px: int | None = None, image_height_px: int | None = None):
        """``(fx, fy, cx, cy)`` in pixels for an image resized to ``image_width_px`` columns.

        Square pixels, principal point at the image centre, pixel (0, 0) = centre of the top-left pixel (OpenCV),
        so ``cx = (width - 1) / 2``. ``image_height_px`` defaults to the native aspect ratio; a different height
        (e.g. the 16:9 mode, a crop of the 4:3 sensor) keeps the focal length.
        """
        width = self.image_width_px if image_width_px is None else image_width_px
        height = round(width * self.image_height_px / self.image_width_px) if image_height_px is None else image_height_px
        focal = self.focal_length_px(width)
        return focal, focal, (width - 1) / 2.0, (height - 1) / 2.0

    @property
    def sensor_height_mm(self) -> float:
        """Sensor height implied by the width and the native aspect ratio (square pixels)."""
        return self.sensor_width_mm * self.image_height_px / self.image_width_px

    @property
    def focal_length_mm(self) -> float:
        """Physical focal length implied by the FOV and the sensor width."""
        return self.focal_length_px() * self.sensor_width_mm / self.image_width_px


@dataclass(frozen=True)
class AircraftProfile:
    """What a mission must respect for one aircraft: speed, camera cadence, gimbal range and endurance; and what
    it can fly at all (horizontal speed, climb and descent rates, the strongest wind it resists, which adds to its
    ground speed), by which a flight log's track is checked (:mod:`capture.flyable`)."""

    name: str
    camera: CameraProfile
    max_speed_m_s: float
    max_ascent_m_s: float
    max_descent_m_s: float
    max_wind_m_s: float
    min_timed_shot_interval_s: float
    rated_flight_time_s: float
    usable_battery_fraction: float
    gimbal_pitch_range_deg: tuple[float, float]
    max_tilt_deg: float = 30.0  # largest pitch or roll the flight controller allows (sport mode)
    gimbal_pitch_mechanical_deg: tuple[float, float] = (-110.0, 35.0)  # the gimbal's stops: no photo beyond them
    max_rotation_rate_deg_s: float = 250.0  # fastest the camera turns: aircraft yaw rate plus gimbal pitch speed
    unverified: tuple[str, ...] = ()

    @property
    def usable_flight_time_s(self) -> float:
        """Mission time one battery allows after keeping a reserve for take-off, transit, wind and landing."""
        return self.rated_flight_time_s * self.usable_battery_fraction


#: The DJI Mini SE's 12 MP 1/2.3" camera in 4:3 mode. 4000x3000 is confirmed by an owner's write-up; the
#: 83 deg diagonal FOV and the 6.17 mm sensor width (1/2.3") are from memory of DJI's spec sheet (UNVERIFIED).
#: Lens calibration (UNVERIFIED for this camera: no Mini SE DewarpData is public): the coefficients of a DJI
#: Mavic 3 Enterprise DewarpData (5280x3956, 2025-02-26; quoted in a public repository's XMP test fixture),
#: k1 -0.108 (barrel: the image corner 9 % towards the centre), and its principal-point offset (20.7, -16.7) px
#: scaled to 4000 px wide. The real P4 Multispectral set (/work/shared/data/p4m_rtk) has a stronger k1 -0.42.
MINI_SE_CAMERA = CameraProfile(
    name="DJI Mini SE FC7103 (4:3)",
    image_width_px=4000,
    image_height_px=3000,
    diagonal_fov_deg=83.0,
    sensor_width_mm=6.17,
    unverified=("diagonal_fov_deg", "sensor_width_mm", "distortion", "principal_point_offset_px"),
    distortion=(-0.107756512758, -0.000878853880, 0.000130474491, -0.000011293710, -0.015723478938),
    principal_point_offset_px=(20.720882112011 * 4000 / 5280, -16.733345702852 * 4000 / 5280),
)

#: DJI Mini SE (2021). Max speed 13 m/s (S mode), the 2 s minimum interval of DJI's timed shots, the -90..0 deg
#: controllable gimbal tilt: UNVERIFIED (research/litchi.md section 4). 30 min rated flight time: Wikipedia
#: and an owner's write-up (rated at 17 km/h without wind). The 80 % usable fraction is our own reserve policy.
#: Max ascent 5 m/s and descent 3.5 m/s (S mode) and wind resistance 8 m/s (level 4): from memory of DJI's spec
#: sheet for the Mini series, UNVERIFIED. Max tilt 30 deg (S mode; 20 deg in P and C) and the gimbal's mechanical
#: pitch range -110..+35 deg (research/litchi.md section 4; DUML gimbal pitch about -90..+47, research/dji-telemetry.md
#: section 2.3): from memory of DJI's Mavic Mini / Mini SE spec sheet, UNVERIFIED; the 250 deg/s camera turn rate
#: is ours (DJI Mini max yaw rate ~130 deg/s by the same memory, plus the gimbal's pitch speed), UNVERIFIED.
DJI_MINI_SE = AircraftProfile(
    name="DJI Mini SE",
    camera=MINI_SE_CAMERA,
    max_speed_m_s=13.0,
    max_ascent_m_s=5.0,
    max_descent_m_s=3.5,
    max_wind_m_s=8.0,
    min_timed_shot_interval_s=2.0,
    rated_flight_time_s=30 * 60.0,
    usable_battery_fraction=0.8,
    gimbal_pitch_range_deg=(-90.0, 0.0),
    max_tilt_deg=30.0,
    gimbal_pitch_mechanical_deg=(-110.0, 35.0),
    max_rotation_rate_deg_s=250.0,
    unverified=("max_speed_m_s", "min_timed_shot_interval_s", "gimbal_pitch_range_deg", "max_ascent_m_s",
                "max_descent_m_s", "max_wind_m_s", "max_tilt_deg", "gimbal_pitch_mechanical_deg",
                "max_rotation_rate_deg_s"),
)

#: Maximum height above take-off allowed without special permission: EU open category 120 m (Regulation
#: 2019/947); US Part 107 allows 400 ft = 121.92 m, so 120 m satisfies both.
LEGAL_MAX_HEIGHT_M = 120.0
#: Diagonal (mm) of the 36 x 24 mm frame that 35 mm-equivalent focal lengths refer to.
FULL_FRAME_DIAGONAL_MM = 43.27
