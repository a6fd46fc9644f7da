"""Timing photos by their shadows (recon/appearance/shadow_timing.py), against known truth: the village of test_delight
photographed by sim under the real sun of a known UTC time over a known place; the true mesh and poses are the twin (no
SfM)."""

import datetime as dt
import math

import numpy as np
import pytest

from flightplan.geodesy import LocalFrame
from recon.inputs.priors import exif_times
from recon.appearance.shadow_timing import (HALF_PEAK_TOLERANCE_H, dark_mask, edge_contrast, fit_utc_offset,
                                            halves_agree, mean_contrast, mean_of_known, predicted_shadow,
                                            refine_capture_time, shadow_views, start_fit, sun_direction,
                                            untextured_scene)
from recon.appearance.texture import Photo
from sim.render.camera import Rig, look_at
from sim.render.renderer import render
from sim.render.scene import Scene, Surface
from sim.render.shade import Lighting, Sun
from sim.sampling.sun import solar_position
from tests.recon.test_atlas import oblique_poses
from tests.recon.test_delight import village
from tests.recon.test_texture import CAMERA

#: A winter afternoon in Turin (the p4m_rtk photos' place and day): a low sun, long shadows.
ORIGIN = LocalFrame(45.0316, 7.6205, 0.0)
UTC = dt.datetime(2026, 1, 26, 12, 50, tzinfo=dt.timezone.utc)
#: The camera clock's zone (CET).
ZONE_H = 1.0


def rotation_z(degrees: float) -> np.ndarray:
    """4x4 turn about the vertical, counter-clockwise seen from above (azimuths fall by ``degrees``)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    turn = np.eye(4)
    turn[:2, :2] = ((c, -s), (s, c))
    return turn


def photographed(sun: Sun, model_turn_deg: float = 0.0) -> tuple:
    """The village, painted a light stone with mild variation, photographed under ``sun`` from six oblique poses:
    (its twin, the photos as recon holds them), the twin and the poses turned by ``model_turn_deg`` (a georeference's
    yaw error)."""
    mesh, _ = village()
    shades = np.random.default_rng(3).uniform(0.85, 1.0, (len(mesh.vertices), 1))
    truth = Scene(mesh.vertices, mesh.faces, Surface(vertex_colors=(shades * (190, 180, 160)).astype(np.uint8)))
    poses = oblique_poses(6, 30.0, 28.0)
    turn = rotation_z(model_turn_deg)
    photos = []
    for k, pose in enumerate(poses):
        rgb = render(truth, Rig((CAMERA,), (np.eye(4),)), pose, sun, lighting=Lighting(exposure=0.6)).views[0].rgb
        photos.append(Photo(f"p{k}.jpg", rgb, CAMERA, turn @ pose))
    vertices = np.asarray(mesh.vertices) @ turn[:3, :3].T
    return untextured_scene(vertices, mesh.faces), photos


def true_sun(utc: dt.datetime = UTC) -> Sun:
    return Sun(*solar_position(ORIGIN.lat0_deg, ORIGIN.lon0_deg, utc))


def clocks(photos, offset_s: float) -> dict[str, float]:
    """Every photo taken at UTC, its clock reading UTC + ``offset_s``."""
    return {photo.name: UTC.timestamp() + offset_s for photo in photos}


@pytest.fixture(scope="module")
def sunny():
    return photographed(true_sun())


def test_the_utc_offset_of_a_local_clock_is_found_from_the_shadows(sunny):
    twin, photos = sunny
    views = shadow_views(twin, photos, clocks(photos, 3600.0 * ZONE_H))
    fit = fit_utc_offset(twin, views, ORIGIN)
    assert fit is not None
    assert fit.zone_h == pytest.approx(ZONE_H)
    assert abs(fit.utc_offset_h - ZONE_H) <= 0.25  # the sun within a quarter of an hour
    assert fit.contrast > fit.before + 0.3 and fit.iou > 0.8


def test_a_photo_that_sees_none_of_the_twin_is_left_out_of_the_timing(sunny):
    """A registered photo beyond the twin (brighton_beach with every fourth photo held out: one photo past the
    subset's mesh failed the texture stage with a broadcasting error) has no shadows to score: it is left out, and
    the others still find the zone."""
    twin, photos = sunny
    skyward = look_at([0.0, 0.0, 50.0], [0.0, 0.1, 500.0])  # above the village, looking up
    away = Photo("sky.jpg", np.zeros_like(photos[0].image), CAMERA, skyward)
    views = shadow_views(twin, [*photos, away], clocks([*photos, away], 3600.0 * ZONE_H))
    assert [view.name for view in views] == [photo.name for photo in photos]
    fit = fit_utc_offset(twin, views, ORIGIN)
    assert fit is not None and fit.zone_h == pytest.approx(ZONE_H)


def test_a_camera_clock_20_minutes_fast_is_corrected(sunny):
    twin, photos = sunny
    views = shadow_views(twin, photos, clocks(photos, 20 * 60.0))
    start = start_fit(twin, views, ORIGIN, 0.0)
    fit = refine_capture_time(twin, views, ORIGIN, start)
    assert fit.clock_correction_min == pytest.approx(-20.0, abs=10.0)
    assert fit.zone_h == pytest.approx(0.0)
    assert fit.contrast > start.contrast


def test_a_right_clock_is_left_alone(sunny):
    twin, photos = sunny
    views = shadow_views(twin, photos, clocks(photos, 0.0))
    fit = refine_capture_time(twin, views, ORIGIN, start_fit(twin, views, ORIGIN, 0.0))
    assert (fit.clock_correction_min, fit.yaw_deg) == (0.0, 0.0)
    assert fit.iou > 0.8


def test_a_model_turned_6_degrees_gets_its_sun_turned_alike():
    """Time and yaw both turn the sun; what matters (and is tested) is the sun in the model's frame."""
    twin, photos = photographed(true_sun(), model_turn_deg=6.0)
    views = shadow_views(twin, photos, clocks(photos, 0.0))
    start = start_fit(twin, views, ORIGIN, 0.0)
    fit = refine_capture_time(twin, views, ORIGIN, start)
    fitted_sun = true_sun(UTC + dt.timedelta(minutes=fit.clock_correction_min))
    assert fitted_sun.azimuth_deg + fit.yaw_deg == pytest.approx(true_sun().azimuth_deg - 6.0, abs=2.5)
    assert fit.contrast > start.contrast + 0.05


def test_a_peak_only_some_of_the_photos_show_is_not_a_fit():
    """Contrast over ten offsets in eight views: where every view peaks at the same offset, every half agrees; where
    the first four peak at 1 h and the last four (weaker) at 3 h, the whole set still peaks at 1 h but its second half
    does not; halves one tolerance apart still agree; views with no contrast known are no half's evidence; three
    views are not split."""
    offsets = np.arange(10, dtype=float)

    def peaked_at(hour, height=1.0):
        return height * np.exp(-0.5 * (offsets - hour) ** 2)

    assert halves_agree(np.column_stack([peaked_at(1.0)] * 8), offsets, 1)
    some = np.column_stack([peaked_at(1.0)] * 4 + [peaked_at(3.0, 0.8)] * 4)
    assert int(np.nanargmax(mean_of_known(some))) == 1 and not halves_agree(some, offsets, 1)
    apart = np.column_stack([peaked_at(2.0)] * 4 + [peaked_at(3.0)] * 4)  # in steps of the tolerance: 1 step apart
    assert halves_agree(apart, offsets * HALF_PEAK_TOLERANCE_H, 2)
    assert not halves_agree(apart, offsets * HALF_PEAK_TOLERANCE_H * 1.01, 2)
    some[:, 4:] = np.nan
    assert not halves_agree(some, offsets, 1)
    assert halves_agree(some[:, :3], offsets, 1)


def test_an_overcast_capture_is_not_timed():
    twin, photos = photographed(Sun(*solar_position(ORIGIN.lat0_deg, ORIGIN.lon0_deg, UTC), 0.0))
    views = shadow_views(twin, photos, clocks(photos, 3600.0 * ZONE_H))
    assert fit_utc_offset(twin, views, ORIGIN) is None


def test_the_edge_contrast_is_the_photos_across_the_predicted_edges(sunny):
    """Lit ground over shadowed ground is sun plus sky over sky: log((1.0 cos + 0.3) / 0.3) on flat open ground under
    the true sun; a sun from elsewhere puts the edges where the photo has none."""
    twin, photos = sunny
    views = shadow_views(twin, photos, clocks(photos, 0.0))
    sun = sun_direction(ORIGIN, UTC.timestamp())
    contrasts = [edge_contrast(view, predicted_shadow(twin, view, sun)) for view in views]
    ground_cos = true_sun().direction_enu[2]
    assert np.median(contrasts) == pytest.approx(np.log((ground_cos + 0.3) / 0.3), abs=0.25)
    assert mean_contrast(twin, views, ORIGIN, 0.0, yaw_deg=90.0) < np.median(contrasts) - 0.3


def test_dark_pixels_are_the_dark_and_blue_ones():
    lit = np.array([200, 180, 150], np.uint8)  # warm sunlight
    shade = np.array([40, 50, 70], np.uint8)  # blue skylight
    image = np.where(np.arange(20)[None, :, None] < 8, shade, lit).repeat(10, axis=0).astype(np.uint8)
    hit = np.ones((10, 20), bool)
    hit[:, -2:] = False
    dark = dark_mask(image, hit)
    assert dark[:, :8].all() and not dark[:, 8:].any()


def test_exif_times_of_photos_without_a_zone_are_their_clocks(shared_data):
    photos = shared_data / "p4m_rtk" / "images"
    utc, clock = exif_times(photos, ["DJI_0010.JPG", "DJI_0020.JPG"])
    assert utc is None
    assert dt.datetime.fromtimestamp(clock[0], dt.timezone.utc).replace(tzinfo=None) == dt.datetime(2026, 1, 26, 13, 50, 17)
    assert 0 < clock[1] - clock[0] < 60
