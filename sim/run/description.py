"""What ``dataset.json`` records of a render's settings (``sampling``): everything that decides the bytes of its frames,
no run details (workers, shard, scheduler). A rerun compares it before it resumes, so its text only changes with
what it describes."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from flightplan.geodesy import LocalFrame
from sim.drone import Imperfections
from sim.drone.flight import GRAVITY_MPS2
from sim.motion.imu import EUROC_ADIS16448, NOISE_MODEL_NAME, T_body_cam0
from sim.render.shade import LIGHT_MODEL
from sim.run.options import RenderOptions
from sim.run.rig import build_rig
from sim.sampling.light import SunSetting, frame_light
from sim.sampling.seeds import IMU_STREAM
from sim.sampling.sun import REFRACTION_PRESSURE_HPA, REFRACTION_TEMPERATURE_C, SUN_STRENGTH_TO_INTENSITY

#: The trajectories kept inside the valid area (and the scene's observed_area_m polygon) less the margin: flown in the
#: largest rectangle inside both (sim/sampling/frustum.py inner_rectangle). Orbit and flight are placed by the user.
MARGIN_PATHS = ("lawnmower", "loop")
#: What ``dataset.json`` says of the frustum margin. The text is part of the settings a rerun compares before it
#: resumes, so it keeps the module path it was written with (now sim/sampling/frustum.py): datasets rendered before
#: the move still resume.
FRUSTUM_MARGIN = ("frustum: every ray of every frame stays inside the valid area and the scene's observed_area_m "
                  "polygon if any (sim/frustum.py)")
#: A trajectory is one flight under one sky: every frame has the sun drawn for frame 0, so consecutive frames differ
#: only by motion (what optical flow, visual odometry and photometric losses assume). Random poses draw one per frame.
SEQUENCE_SUN = "one per sequence: frame 0's draw, for every frame"
#: What ``dataset.json`` says of unlit frames (a replay of the scene's cameras unless another sun is asked for).
UNLIT_LIGHTING = "unlit (the texture's own shading, UNLIT)"
#: What ``dataset.json`` says of the real sun's position and strength (``--sun time:``).
REAL_SUN = {"position": f"apparent (refraction-corrected at {REFRACTION_PRESSURE_HPA} hPa, "
                        f"{REFRACTION_TEMPERATURE_C} C), over the origin, PyEphem",
            "strength_model": "clear sky: Meinel's direct beam through Kasten-Young air mass, 10 at the zenith"}


def sampling_description(options: RenderOptions, origin: LocalFrame) -> dict:
    """What ``dataset.json`` records about the sampling (settings that decide the bytes, no run details); ``origin``
    is the scene's (where the real sun of ``--sun time:`` is computed)."""
    poses = options.poses
    description = {"mode": poses.mode, "seed": options.seed, "samples_per_pixel": options.rig.spp,
                   "sun_strength_to_intensity": SUN_STRENGTH_TO_INTENSITY, "light_model": LIGHT_MODEL}
    if poses.mode == "random":
        description["random"] = asdict(poses.random_settings())
    elif poses.mode == "trajectory":
        description["trajectory"] = {"path": poses.trajectory, "altitude_m": poses.altitude_m,
                                     "speed_m_s": poses.speed_m_s, "frame_rate_hz": poses.frame_rate_hz}
        if poses.trajectory == "flight":
            description["trajectory"] = {"path": "flight", "mission": Path(poses.mission).name,
                                         "imperfections": Imperfections.realistic().to_dict(),
                                         "frame_rate_hz": poses.frame_rate_hz}
        if poses.imu_rate_hz is not None:
            description["imu"] = imu_description(options)
    elif poses.replays_scene_cameras:
        description["cameras"] = "cameras.json"
    else:
        description["geotags"] = Path(poses.geotags).name
    description.update(light_description(options.light.setting(poses), poses.mode, origin))
    inside_margin = poses.mode == "random" or (poses.mode == "trajectory" and poses.trajectory in MARGIN_PATHS)
    if inside_margin and poses.margin_m is None:
        description["margin"] = FRUSTUM_MARGIN
    elif inside_margin and poses.mode == "trajectory":
        description["trajectory"]["margin_m"] = poses.margin_m
    if options.effects.enabled:
        description["effects"] = options.effects.description()
    return json.loads(json.dumps(description))  # as read back from dataset.json (lists, not tuples)


def light_description(setting: SunSetting, mode: str, origin: LocalFrame) -> dict:
    """What ``dataset.json`` says of the light: nothing for the paper's random sun per frame (:data:`SEQUENCE_SUN` for
    a trajectory's one), ``lighting`` :data:`UNLIT_LIGHTING` for unlit frames, otherwise ``sun``: the sun every frame
    has (its frame record, with :data:`REAL_SUN` for the time form)."""
    if setting.form == "random":
        return {"sun": SEQUENCE_SUN} if mode == "trajectory" else {}
    if setting.form == "unlit":
        return {"lighting": UNLIT_LIGHTING}
    record = frame_light(setting, 0, 0, origin).record
    return {"sun": {**record, **REAL_SUN} if setting.form == "time" else record}


def imu_description(options: RenderOptions) -> dict:
    """What ``dataset.json`` says about the IMU: rate, noise figures and source, gravity, extrinsics."""
    T_body_cam = T_body_cam0(options.rig.baseline_m)
    return {"rate_hz": options.poses.imu_rate_hz, "file": "imu/NN.csv (NN = the sequence)",
            "noise_model": NOISE_MODEL_NAME, "noise": EUROC_ADIS16448.to_dict(),
            "noise_seed": f"numpy default_rng([seed, {IMU_STREAM}])", "gravity_m_s2": GRAVITY_MPS2,
            "trajectory": "smooth (sim/motion): the body (IMU) frame follows the path; frames rendered on it",
            "body_frame": "IMU axes: x along the left camera's optical axis, y to its left, z up in the image",
            "T_body_cam": [(T_body_cam @ T_rig_cam).tolist() for T_rig_cam in build_rig(options.rig).T_rig_cam]}
