"""mcslam: semantic RGB-D SLAM for dynamic indoor scenes, from Python.

    import mcslam
    seq = mcslam.Sequence("rgbd_dataset_freiburg1_xyz")
    system = mcslam.System(seq.directory)          # camera chosen as `mcslam run` chooses it
    for k in range(len(seq)):
        rgb, depth, t, _ = seq.load(k, system.camera.depth_factor)
        frame = system.process(rgb, depth, t)      # frame.state, frame.pose (4 x 4 or None)
    system.finish()
    print(mcslam.eval(seq.groundtruth(), system.trajectory())["ate_rmse_m"])

Images are numpy arrays: colour uint8 (H, W, 3) in BGR order (as cv2.imread gives; pass
rgb_order=True for RGB) or (H, W) grey; depth float32 in metres or uint16 in the camera's raw
units. Trajectories are N x 8 float64 arrays of TUM rows (timestamp tx ty tz qx qy qz qw, the
camera's pose in the world). Bad input raises mcslam.InputError (a ValueError) whose message
names the file or argument and the problem.
"""

import json
import os

from ._mcslam import (  # noqa: F401  (the public API)
    Camera,
    Frame,
    InputError,
    Sequence,
    Settings,
    __version__,
    data_file_candidates,
    read_trajectory,
    write_trajectory,
)
from ._mcslam import _evaluate, _System

__all__ = [
    "Camera",
    "Frame",
    "InputError",
    "Sequence",
    "Settings",
    "System",
    "__version__",
    "eval",
    "make_settings",
    "read_trajectory",
    "run",
    "write_trajectory",
]


def _yaml_value(value):
    # numpy scalars (np.int64(1500), np.float32, np.bool_) as the Python numbers they hold:
    # repr() of them is "np.int64(1500)" with numpy >= 2.
    if hasattr(value, "item") and hasattr(value, "dtype") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_yaml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value)  # a double-quoted YAML scalar
    return repr(value)


def make_settings(camera, settings=None, *, sequential=None, vocabulary=None,
                  loop_closing=None, model=None, confidence=None, detections=None):
    """Settings from a camera and options.

    camera: a Settings; a Camera; a preset name ("tum_fr1", "tum_fr2", "tum_fr3", "bonn"); a
        TUM-layout folder (its preset by name, then its camera.yaml, as `mcslam run`); or a
        settings file holding the camera (camera.fx ... or ORB-SLAM2's Camera.fx ...).
    settings: None; a settings file; or a dict of settings keys, e.g.
        {"orb.num_features": 1500, "system.sequential": True}.
    model / confidence: an ONNX detector (YOLOv8/YOLO11 or YOLOX export) for object boxes;
        detections: a detections file instead. Without either, geometry only.
    """
    if isinstance(camera, Settings):
        s = Settings(camera)  # a copy: the options below do not change the caller's
    elif isinstance(camera, Camera):
        s = Settings()
        s.camera = camera
    elif isinstance(camera, (str, os.PathLike)):
        name = os.fspath(camera)
        if os.path.isdir(name):
            s = Settings.for_sequence(name)
        elif os.path.isfile(name):
            s = Settings()
            s.load_file(name)
        elif os.sep in name or name.startswith("."):
            raise InputError(f"{name}: no such folder or file (camera: a preset name, a "
                             "sequence folder or a settings file)")
        else:
            s = Settings.preset(name)  # raises InputError naming the known presets
    else:
        raise InputError("camera: expected a Settings, a Camera, a preset name, a sequence "
                         "folder or a settings file, got " + type(camera).__name__)
    if settings is not None:
        if isinstance(settings, dict):
            text = "".join(f"{k}: {_yaml_value(v)}\n" for k, v in settings.items())
            s.load_yaml(text, "settings")
        elif isinstance(settings, (str, os.PathLike)):
            s.load_file(os.fspath(settings))
        else:
            raise InputError("settings: expected a dict or a settings file, got "
                             + type(settings).__name__)
    if sequential is not None:
        s.sequential = bool(sequential)
    if vocabulary is not None:
        s.vocabulary = os.fspath(vocabulary)
    if loop_closing is not None:
        s.set_loop_closing(bool(loop_closing))
    if model is not None:
        s.set_detector(os.fspath(model), confidence)
    if detections is not None:
        s.set_detections_file(os.fspath(detections))
    return s


class System(_System):
    """The SLAM system. System(camera, settings=None, **options): see make_settings().

    process(rgb, depth, timestamp, depth_timestamp=None, rgb_order=False) -> Frame
    finish(); trajectory(), unsmoothed_trajectory(), keyframe_trajectory(),
    online_trajectory(), lagged_trajectory() -> N x 8 arrays (Frame.lagged_pose and
    lagged_trajectory() with tracker.pose_filter.lag > 0);
    map() -> {"points": N x 3, "lines": N x 6 (two endpoints), "planes": N x 4 (n, d),
    "keyframes": N x 8}; grid() -> {"cells": H x W int8 (nav_msgs: -1 unknown, 0 free,
    100 occupied; row 0 the lowest y), "resolution": metres, "T_world_grid": 4 x 4};
    occupied_voxels() -> N x 3 (world frame); save_session(path).
    """

    def __init__(self, camera, settings=None, **options):
        super().__init__(make_settings(camera, settings, **options))

    @property
    def camera(self):
        return self.settings.camera

    def points(self):
        return self.map()["points"]

    def lines(self):
        return self.map()["lines"]

    def planes(self):
        return self.map()["planes"]


def _trajectory(value, what):
    if isinstance(value, (str, os.PathLike)):
        return read_trajectory(os.fspath(value))
    if value is None:
        raise InputError(f"{what}: no trajectory (None)")
    return value


def eval(groundtruth, estimate, max_time_difference=0.02):  # noqa: A001 (as `mcslam eval`)
    """ATE and RPE of `estimate` against `groundtruth` (N x 8 arrays or TUM files), as
    `mcslam eval --json`: a dict with ate_rmse_m, rpe_frame_trans_rmse_m, matched, ..."""
    return json.loads(_evaluate(_trajectory(groundtruth, "groundtruth"),
                                _trajectory(estimate, "estimate"), max_time_difference))


def run(sequence, settings=None, *, max_frames=0, progress=None, **options):
    """Runs a TUM-layout folder through a System (sequential unless said otherwise) and returns
    it finished. progress(k, frame) is called after each frame."""
    seq = sequence if isinstance(sequence, Sequence) else Sequence(os.fspath(sequence))
    options.setdefault("sequential", True)
    system = System(seq.directory, settings, **options)
    factor = system.camera.depth_factor
    n = len(seq) if max_frames <= 0 else min(len(seq), max_frames)
    for k in range(n):
        rgb, depth, t, t_depth = seq.load(k, factor)
        frame = system.process(rgb, depth, t, t_depth)
        if progress is not None:
            progress(k, frame)
    system.finish()
    return system
