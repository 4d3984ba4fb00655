"""A trajectory as a LeRobot dataset (LeRobotDataset v3.0 layout, one episode), for learning
pipelines: ``observation.state`` the joint positions, ``action`` the next frame's (the last frame
holds), the joints by name as the features' ``names``, at the trajectory's frame rate.

Written with pyarrow in the layout LeRobot documents and its own writer produces
(huggingface/lerobot, ``datasets/utils.py``, ``io_utils.py``, ``dataset_metadata.py``): the
``lerobot`` package itself needs PyTorch, which hlik does not. Files::

    meta/info.json                                codebase_version v3.0, fps, features, paths
    meta/stats.json                               per feature: min, max, mean, std, count, q01..q99
    meta/tasks.parquet                            the task string as the (pandas) index, task_index
    meta/episodes/chunk-000/file-000.parquet      the episode: length, tasks, where its rows are, stats
    data/chunk-000/file-000.parquet               one row per frame
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from hlik.robot.model import Robot
from hlik.trajectory import Trajectory
from hlik.util.errors import HlikError

VERSION = "v3.0"
DATA = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
# LeRobot's own per-frame columns (its DEFAULT_FEATURES)
INDEX_FEATURES = {
    name: {"dtype": dtype, "shape": [1], "names": None}
    for name, dtype in (
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    )
}


def task(traj: Trajectory, robot: Robot) -> str:
    """The episode's task string: the motion (its file's name, else its own) on the robot."""
    motion = Path(traj.motion.source).stem if traj.motion.source else traj.motion.name
    return f"{motion} retargeted to {robot.title} by hlik ({traj.solver})"


def write(traj: Trajectory, robot: Robot, path: Path, violation: str | None = None, braking: int = 0) -> None:
    """Write ``traj`` as a dataset into the folder ``path`` (see the module docstring); a
    ``violation`` (exported with ``--allow-violations``) is kept in ``info.json`` as
    ``hlik_violation``, and ``braking`` (how many of the last frames bring the joints to rest,
    :mod:`hlik.braking`) as ``hlik_braking_frames``.

    Raises:
        HlikError: a frame rate that is not a whole number of frames per second (LeRobot's fps is
            an integer; resample with ``hlik run --rate``).
    """
    fps = 1.0 / traj.period
    if abs(fps - round(fps)) > 1e-6 * fps:
        raise HlikError(
            f"{path}: LeRobot needs a whole frame rate, the trajectory's is {fps:g} Hz (hlik run --rate)"
        )
    state = traj.q.astype(np.float32)
    action = np.concatenate([state[1:], state[-1:]])  # the next frame's joint positions
    n, dof = state.shape
    columns = {
        "observation.state": state,
        "action": action,
        "timestamp": (traj.times - traj.times[0]).astype(np.float32),
        "frame_index": np.arange(n, dtype=np.int64),
        "episode_index": np.zeros(n, dtype=np.int64),
        "index": np.arange(n, dtype=np.int64),
        "task_index": np.zeros(n, dtype=np.int64),
    }
    features = {
        key: {"dtype": "float32", "shape": [dof], "names": list(robot.joint_names)}
        for key in ("observation.state", "action")
    } | INDEX_FEATURES
    stats = {key: _stats(np.asarray(values).reshape(n, -1)) for key, values in columns.items()}
    _write_table(path / DATA.format(chunk_index=0, file_index=0), _table(columns))
    _write_table(path / "meta" / "tasks.parquet", _tasks(task(traj, robot)))
    _write_table(path / EPISODES.format(chunk_index=0, file_index=0), _episodes(traj, robot, n, stats))
    info = _info(robot, n, int(round(fps)), features, violation) | {"hlik_braking_frames": braking}
    (path / "meta" / "info.json").write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    (path / "meta" / "stats.json").write_text(json.dumps(stats, indent=2) + "\n", encoding="utf-8")


def _episodes(traj: Trajectory, robot: Robot, n: int, stats: dict) -> pa.Table:
    """``meta/episodes``: the one episode of ``n`` frames with its task and per-feature stats."""
    episode: dict[str, object] = {
        "episode_index": 0,
        "tasks": [task(traj, robot)],
        "length": n,
        "data/chunk_index": 0,
        "data/file_index": 0,
        "dataset_from_index": 0,
        "dataset_to_index": n,
        "meta/episodes/chunk_index": 0,
        "meta/episodes/file_index": 0,
    }
    episode |= {f"stats/{key}/{stat}": value for key, s in stats.items() for stat, value in s.items()}
    return pa.Table.from_pylist([episode])


def _info(robot: Robot, n: int, fps: int, features: dict, violation: str | None) -> dict:
    """``meta/info.json``: the dataset's layout, features and, where exported anyway, the violation."""
    info = {
        "codebase_version": VERSION,
        "robot_type": robot.name,
        "total_episodes": 1,
        "total_frames": n,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": fps,
        "splits": {"train": "0:1"},
        "data_path": DATA,
        "video_path": None,
        "features": features,
    }
    if violation is not None:
        info["hlik_violation"] = (
            f"exported with --allow-violations; a controller would reject it: {violation}"
        )
    return info


def _table(columns: dict[str, np.ndarray]) -> pa.Table:
    """The per-frame table: vectors as fixed-size lists, as LeRobot's writer stores them."""
    arrays = {}
    for key, values in columns.items():
        if values.ndim == 2:
            flat = pa.array(values.reshape(-1), type=pa.float32())
            arrays[key] = pa.FixedSizeListArray.from_arrays(flat, values.shape[1])
        else:
            arrays[key] = pa.array(values)
    return pa.table(arrays)


def _tasks(text: str) -> pa.Table:
    """``meta/tasks.parquet``: pandas reads the task strings back as the index named ``task``."""
    table = pa.table({"task_index": pa.array([0], type=pa.int64()), "task": pa.array([text])})
    column = lambda name, kind, numpy: {  # noqa: E731
        "name": name, "field_name": name, "pandas_type": kind, "numpy_type": numpy, "metadata": None
    }  # fmt: skip
    pandas = {
        "index_columns": ["task"],
        "column_indexes": [],
        "columns": [column("task_index", "int64", "int64"), column("task", "unicode", "object")],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.0",
    }
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas).encode()})


def _stats(values: np.ndarray) -> dict[str, list]:
    """min, max, mean, std, count and quantiles of (F, k) values, per component (LeRobot's
    ``compute_episode_stats``; counts as a one-element list)."""
    values = values.astype(np.float64)
    out = {
        "min": values.min(axis=0).tolist(),
        "max": values.max(axis=0).tolist(),
        "mean": values.mean(axis=0).tolist(),
        "std": values.std(axis=0).tolist(),
        "count": [len(values)],
    }
    for q in QUANTILES:
        out[f"q{round(100 * q):02d}"] = np.quantile(values, q, axis=0).tolist()
    return out


def _write_table(path: Path, table: pa.Table) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, path, compression="snappy")
