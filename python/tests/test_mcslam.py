"""The Python bindings: a synthetic sequence through System.process gives the trajectory of
`mcslam run --sequential`; bad input raises mcslam.InputError naming the problem."""
import os
import subprocess
import sys

import numpy as np
import pytest

import mcslam

HERE = os.path.dirname(os.path.abspath(__file__))


def test_version_is_the_cli_version(mcslam_exe):
    out = subprocess.run([mcslam_exe, "--version"], check=True, capture_output=True, text=True)
    assert out.stdout.strip() == f"mcslam {mcslam.__version__}"
    assert mcslam.__version__.count(".") == 2


@pytest.fixture(scope="module")
def python_run(synth_sequence):
    """The synthetic sequence through System.process, frame by frame, and what came back."""
    seq = mcslam.Sequence(synth_sequence)
    system = mcslam.System(synth_sequence, sequential=True)
    frames = []
    for k in range(len(seq)):
        rgb, depth, t, t_depth = seq.load(k, system.camera.depth_factor)
        assert rgb.dtype == np.uint8 and rgb.shape == (480, 640, 3)
        assert depth.dtype == np.float32 and depth.shape == (480, 640)
        frames.append(system.process(rgb, depth, t, t_depth))
    system.finish()
    return seq, system, frames


def test_process_gives_the_cli_trajectory(python_run, cli_run):
    seq, system, frames = python_run
    ours = system.trajectory()
    cli = mcslam.read_trajectory(os.path.join(cli_run, "trajectory.txt"))
    assert ours.shape == cli.shape and ours.shape[0] >= 25 and ours.shape[1] == 8
    assert np.max(np.abs(ours[:, 0] - cli[:, 0])) <= 1e-6
    assert np.max(np.linalg.norm(ours[:, 1:4] - cli[:, 1:4], axis=1)) <= 1e-6
    assert [f.state for f in frames].count("ok") >= 25
    assert frames[-1].state == "ok"
    # The same poses before their positions were smoothed.
    raw = system.unsmoothed_trajectory()
    cli_raw = mcslam.read_trajectory(os.path.join(cli_run, "trajectory_unsmoothed.txt"))
    assert raw.shape == ours.shape and np.array_equal(raw[:, 0], ours[:, 0])
    assert np.max(np.linalg.norm(raw[:, 1:4] - cli_raw[:, 1:4], axis=1)) <= 1e-6
    assert np.array_equal(raw[:, 4:8], ours[:, 4:8])


def test_frame_pose_is_a_4x4_rigid_transform(python_run):
    _, system, frames = python_run
    pose = frames[-1].pose
    assert pose.shape == (4, 4) and pose.dtype == np.float64
    assert np.allclose(pose[3], [0, 0, 0, 1])
    assert np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-9)
    online = system.online_trajectory()
    assert np.allclose(online[-1, 1:4], pose[:3, 3], atol=1e-6)
    # Keyframes inserted, some perhaps culled since.
    assert sum(f.keyframe for f in frames) >= len(system.keyframe_trajectory()) >= 1


def test_lagged_pose_trails_the_frame_by_the_lag(synth_sequence):
    """tracker.pose_filter.lag: each frame gives the pose of the frame `lag` tracked frames back
    (with its own timestamp); lagged_trajectory() has every tracked frame after finish()."""
    seq = mcslam.Sequence(synth_sequence)
    lag = 4
    system = mcslam.System(synth_sequence, {"tracker.pose_filter.enabled": True,
                                            "tracker.pose_filter.lag": lag}, sequential=True)
    frames = []
    for k in range(min(len(seq), 20)):
        rgb, depth, t, t_depth = seq.load(k, system.camera.depth_factor)
        frames.append(system.process(rgb, depth, t, t_depth))
    assert all(f.state == "ok" for f in frames)
    assert all(f.lagged_pose is None for f in frames[:lag])
    for k in range(lag, len(frames)):
        t, pose = frames[k].lagged_pose
        assert t == frames[k - lag].timestamp
        assert pose.shape == (4, 4) and np.allclose(pose[3], [0, 0, 0, 1])
        # Smoothed, not the immediate pose, and near it (millimetres on the render).
        assert np.linalg.norm(pose[:3, 3] - frames[k - lag].pose[:3, 3]) < 0.02
    system.finish()
    lagged = system.lagged_trajectory()
    assert np.array_equal(lagged[:, 0], system.online_trajectory()[:, 0])


def test_map_as_arrays(python_run):
    _, system, _ = python_run
    m = system.map()
    assert m["points"].shape[1] == 3 and m["points"].shape[0] > 100
    assert m["lines"].shape[1] == 6
    assert m["planes"].shape[1] == 4
    if len(m["planes"]):
        assert np.allclose(np.linalg.norm(m["planes"][:, :3], axis=1), 1.0)
    assert m["keyframes"].shape[1] == 8
    assert np.array_equal(system.points(), m["points"])


def test_eval_against_ground_truth(python_run, cli_run):
    seq, system, _ = python_run
    gt = seq.groundtruth()
    assert gt is not None and gt.shape[1] == 8
    result = mcslam.eval(gt, system.trajectory())
    assert result["matched"] == len(system.trajectory())
    assert 0 <= result["ate_rmse_m"] < 0.05
    assert "rpe_frame_trans_rmse_m" in result
    # Files work too and give the same numbers.
    from_files = mcslam.eval(os.path.join(seq.directory, "groundtruth.txt"),
                             os.path.join(cli_run, "trajectory.txt"))
    assert abs(from_files["ate_rmse_m"] - result["ate_rmse_m"]) < 1e-6


def test_uint16_depth_and_rgb_order(synth_sequence, python_run):
    """Raw depth units are divided by the camera's depth_factor as a depth PNG is; RGB order
    is swapped back to BGR: the first 10 frames track exactly as with float metres and BGR."""
    seq, _, frames = python_run
    system = mcslam.System(synth_sequence, sequential=True)
    factor = system.camera.depth_factor
    for k in range(10):
        rgb, depth, t, t_depth = seq.load(k, factor)
        raw = np.round(depth.astype(np.float64) * factor).astype(np.uint16)
        frame = system.process(np.ascontiguousarray(rgb[:, :, ::-1]), raw, t, t_depth,
                               rgb_order=True)
        assert frame.state == frames[k].state
        if frame.pose is not None:
            assert np.allclose(frame.pose, frames[k].pose, atol=1e-9)


def test_save_session(python_run, tmp_path):
    _, system, _ = python_run
    path = tmp_path / "map.session"
    system.save_session(str(path))
    assert path.stat().st_size > 1000


def test_settings_dict_and_file(synth_sequence, tmp_path):
    s = mcslam.make_settings(synth_sequence, {"orb.num_features": 700, "system.sequential": True})
    assert s.sequential
    assert "num_features: 700" in s.to_yaml()
    f = tmp_path / "s.yaml"
    f.write_text("orb:\n  num_features: 900\n")
    s = mcslam.make_settings(synth_sequence, str(f))
    assert "num_features: 900" in s.to_yaml()
    cam = mcslam.Settings.preset("tum_fr1").camera
    assert cam.width == 640 and cam.fx > 500
    s = mcslam.make_settings(cam)
    assert s.camera.fx == cam.fx


@pytest.fixture(scope="module")
def small_system():
    return mcslam.System("tum_fr1", vocabulary="")


def raises(match, f, *args, **kwargs):
    with pytest.raises(mcslam.InputError, match=match) as info:
        f(*args, **kwargs)
    return str(info.value)


def test_bad_images_raise(small_system):
    rgb = np.zeros((480, 640, 3), np.uint8)
    depth = np.zeros((480, 640), np.float32)
    raises("rgb has dtype float64; expected uint8", small_system.process,
           rgb.astype(np.float64), depth, 0.0)
    raises(r"rgb has shape \(480, 640, 4\)", small_system.process,
           np.zeros((480, 640, 4), np.uint8), depth, 0.0)
    raises("depth has dtype float64", small_system.process, rgb, depth.astype(np.float64), 0.0)
    raises(r"depth has shape \(480, 640, 1\)", small_system.process, rgb, depth[:, :, None], 0.0)
    raises("the colour image is 320x240 but the camera is 640x480", small_system.process,
           np.zeros((240, 320, 3), np.uint8), depth, 0.0)
    raises("the depth image is 640x240", small_system.process, rgb, depth[:240], 0.0)
    raises("rgb must be a numpy array, not str", small_system.process, "not an image", depth, 0.0)
    raises("depth must be a numpy array, not list", small_system.process, rgb, [[0.0]], 0.0)
    # A view that is not contiguous is fine.
    wide = np.zeros((480, 1280, 3), np.uint8)
    assert small_system.process(wide[:, ::2], depth, 1.0).state == "not_initialized"
    assert issubclass(mcslam.InputError, ValueError)


def test_missing_files_raise(tmp_path):
    missing = str(tmp_path / "nowhere")
    raises("nowhere", mcslam.Sequence, missing)
    raises("nowhere", mcslam.read_trajectory, missing)
    raises("nowhere", mcslam.System, "tum_fr1", missing)  # a settings file
    raises("unknown camera preset 'kinect9'", mcslam.System, "kinect9")
    raises("nowhere: no such folder or file", mcslam.System, missing)
    raises("model.onnx", mcslam.System, "tum_fr1", model=str(tmp_path / "model.onnx"))
    raises("detections.json", mcslam.System, "tum_fr1",
           detections=str(tmp_path / "detections.json"))
    bad = tmp_path / "bad.yaml"
    bad.write_text("orb:\n  num_features: lots\n")
    raises("bad.yaml", mcslam.System, "tum_fr1", str(bad))
    raises("no_such_key", mcslam.System, "tum_fr1", {"tracker.no_such_key": 1})
    raises("groundtruth: expected an N x 8 array", mcslam.eval, np.zeros((3, 7)), np.zeros((3, 8)))


def test_example_script_plots(synth_sequence, tmp_path):
    png = tmp_path / "plot.png"
    env = dict(os.environ, MPLBACKEND="Agg")
    out = subprocess.run([sys.executable, os.path.join(HERE, "..", "examples", "run_and_plot.py"),
                          synth_sequence, "--output", str(png), "--max-frames", "20"],
                         check=True, capture_output=True, text=True, env=env)
    assert "ATE RMSE" in out.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_detections_as_the_detector_option(mcslam_exe, synth_sequence, tmp_path):
    """Boxes from a detections file (the synthetic sequence's oracle boxes; a model would be
    System(..., model="yolov8n.onnx")): the same poses as `mcslam run --detections`."""
    boxes = os.path.join(synth_sequence, "detections.json")
    subprocess.run([mcslam_exe, "run", synth_sequence, "--output", str(tmp_path), "--sequential",
                    "--detections", boxes, "-q"], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    system = mcslam.run(synth_sequence, detections=boxes)
    assert system.settings.detections_file == boxes
    cli = mcslam.read_trajectory(os.path.join(str(tmp_path), "trajectory.txt"))
    ours = system.trajectory()
    assert ours.shape == cli.shape
    assert np.max(np.linalg.norm(ours[:, 1:4] - cli[:, 1:4], axis=1)) <= 1e-6
    objects = []
    mcslam.run(synth_sequence, detections=boxes, max_frames=5,
               progress=lambda k, frame: objects.append(frame.objects))
    assert sum(objects) > 0


def test_numpy_scalars_as_settings(synth_sequence):
    # numpy >= 2 prints np.int64(1500) for repr(): the settings take the number it holds.
    s = mcslam.make_settings(synth_sequence, {"orb.num_features": np.int64(1500),
                                              "orb.scale_factor": np.float32(1.25),
                                              "system.sequential": np.bool_(True)})
    assert "num_features: 1500" in s.to_yaml()
    assert "scale_factor: 1.25" in s.to_yaml()
    assert s.sequential


def test_two_threads_on_one_system_are_serialised(synth_sequence):
    # process() runs without the GIL: two Python threads driving one System take turns on its
    # lock, and every call gets its own frame (ids 0..n-1, none twice).
    import threading
    seq = mcslam.Sequence(synth_sequence)
    system = mcslam.System(synth_sequence, sequential=True, vocabulary="")
    rgb, depth, t, _ = seq.load(0, system.camera.depth_factor)
    ids, errors = [], []

    def drive(k):
        try:
            for i in range(12):
                ids.append(system.process(rgb, depth, t + 0.001 * (2 * i + k)).frame_id)
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=drive, args=(k,)) for k in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    system.finish()
    assert not errors
    assert sorted(ids) == list(range(24))


def test_occupancy_grid_and_voxels(python_run):
    # The dense map of the synthetic room: a floor grid with free and occupied cells, and the
    # occupied voxels in the world frame, within the room (walls 3-4 m from the start).
    _, system, _ = python_run
    g = system.grid()
    cells = g["cells"]
    assert cells.dtype == np.int8 and cells.ndim == 2 and cells.size > 0
    assert (cells == 100).sum() > 0 and (cells == 0).sum() > 0
    assert set(np.unique(cells)) <= {-1, 0, 100}
    assert abs(g["resolution"] - 0.05) < 1e-12
    T = g["T_world_grid"]
    assert T.shape == (4, 4) and np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
    v = system.occupied_voxels()
    assert v.ndim == 2 and v.shape[1] == 3 and len(v) > 100
    assert np.abs(v).max() < 10.0
