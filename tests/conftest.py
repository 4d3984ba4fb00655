"""Shared fixtures. Recorded motion comes from ../shared/motion_data (override: HLIK_DATA).

In CI (CI=true) a missing data file fails the test; elsewhere the test is skipped with the reason.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from hlik.robot.files import available_robots
from hlik.util.paths import robots_dir

DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))


def data_file(relative: str) -> Path:
    path = DATA / relative
    if not path.exists():
        message = f"recorded motion {path} not found (set HLIK_DATA to the motion_data folder)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(message)
        pytest.skip(message)
    return path


def kit_takes() -> list[Path]:
    folder = data_file("kit_bimanual")
    takes = sorted(folder.glob("*.xml"))
    if not takes:
        data_file("kit_bimanual/<no .xml takes>")
    return takes


G1 = robots_dir() / "examples" / "g1.toml"  # the worked example robot (the g1 extra)


def require_g1() -> None:
    """Skip (fail in CI) unless example-robot-data, which holds the G1's URDF, is installed."""
    from hlik.robot.model_file import resolve_package
    from hlik.util.errors import RobotError

    try:
        resolve_package("package://example-robot-data/", G1, {})
    except RobotError as e:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(str(e))
        pytest.skip(f'{e} (pip install -e ".[g1]")')


@pytest.fixture(scope="session")
def takes() -> list[Path]:
    return kit_takes()


@pytest.fixture(scope="session")
def cut_take(takes) -> Path:
    """The Cut take (subject 1723 cutting, 10.6 s): objects with markers, one without."""
    (path,) = [p for p in takes if p.name.startswith("Cut_")]
    return path


@pytest.fixture(autouse=True, scope="session")
def _private_cache(tmp_path_factory):
    """Learned criteria are cached in a per-session folder, never in the user's cache; the user's
    settings are never read or written; commands learn from the bundled demo unless a test says
    otherwise (the shared KIT takes would be found beside the checkout)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HLIK_CACHE", str(tmp_path_factory.mktemp("hlik-cache")))
        mp.setenv("XDG_CONFIG_HOME", str(tmp_path_factory.mktemp("config")))
        mp.setenv("HLIK_CORPUS", "demo")
        yield


@pytest.fixture(scope="session")
def reachable_targets():
    """``f(robot, motion) -> HandTargets``: the robot's TCP poses along the clipped joint mapping.

    Human-like and reachable by construction, unlike the recorded hand poses, which a robot's joint
    limits (ARMAR-III's forearm, for one) may put out of reach.
    """
    from hlik.problem.targets import HandTargets
    from hlik.robot.model import joint_mapping, tcp_poses

    def make(robot, motion):
        return HandTargets(*tcp_poses(robot, joint_mapping(robot, motion)))

    return make


def solve_problem(solve, robot, motion, targets, placement, settings=None, learned=None, **kwargs):
    """Run a solver module's ``solve`` on the problem of ``motion`` with the given targets (and
    ``learned`` pieces; learned for the settings' criteria if None).

    Returns the joint angles (T, n) and the :class:`~hlik.solvers.base.SolverResult`.
    """
    from dataclasses import replace

    from hlik.problem.problem import build_problem

    criteria = getattr(settings, "criteria", ())
    problem = replace(build_problem(motion, robot, placement, learned, criteria), targets=targets)
    result = solve(problem, settings, **kwargs) if settings is not None else solve(problem, **kwargs)
    return result.q, result


@pytest.fixture(params=available_robots())
def robot(request):
    """Each bundled robot in turn."""
    from hlik.robot.model import load_robot

    return load_robot(request.param)


ROBOTS = available_robots()


def central_differences(fun, q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """d fun / dq by central differences over q's last axis: q (..., n) -> (..., m, n) for
    fun(q) (..., m)."""
    cols = []
    for j in range(q.shape[-1]):
        dq = np.zeros_like(q)
        dq[..., j] = eps
        cols.append((fun(q + dq) - fun(q - dq)) / (2 * eps))
    return np.stack(cols, axis=-1)


def slowed(motion, factor: float):
    """``motion`` played ``factor`` times slower: robot targets made from it stay within the robots'
    joint speed limits (human arms move faster than ARMAR-III's 1 rad/s)."""
    from dataclasses import replace

    return replace(motion, times=motion.times[0] + factor * (motion.times - motion.times[0]))


def reachable_stretch(robot, take, start: float, stop: float, factor: float = 3.0):
    """``take`` from ``start`` to ``stop`` s, played ``factor`` times slower at 100 Hz, with targets
    the robot can reach (its own TCP poses along the joint mapping) and the robot at the shoulders:
    (motion, targets, placement)."""
    from hlik.human.kinematics import forward_kinematics
    from hlik.human.load import load_motion
    from hlik.problem.placement import shoulder_placement
    from hlik.problem.targets import HandTargets
    from hlik.robot.model import joint_mapping, tcp_poses

    motion = slowed(load_motion(take, rate=100).crop(start, stop), factor).resample(100.0)
    targets = HandTargets(*tcp_poses(robot, joint_mapping(robot, motion)))
    return motion, targets, shoulder_placement(robot, forward_kinematics(motion))


def hand_errors(robot, q, targets) -> tuple[float, float]:
    """The largest position (m) and orientation (rad) error of either hand after the first frame
    of joint angles ``q`` (T, n) against ``targets``."""
    from hlik.criteria.functional import rotation_angle
    from hlik.robot.state import robot_state

    state = robot_state(robot, q)
    pos = np.linalg.norm(state.tcp - targets.pos, axis=-1)[1:]
    return float(pos.max()), float(rotation_angle(state.tcp_rot, targets.rot)[1:].max())


def random_frame(robot, seed: int):
    """A frame of the demo on ``robot`` with a random configuration near home and a moving history:
    the sample and the configuration (n,)."""
    from hlik.human.demo import demo_motion
    from hlik.problem.problem import build_problem
    from hlik.solvers.frames import sample_at

    rng = np.random.default_rng(seed)
    problem = build_problem(demo_motion().crop(1.0, 1.4), robot)
    lower, upper = np.maximum(robot.lower, -2.5), np.minimum(robot.upper, 2.5)
    q = np.clip(robot.home + rng.normal(0, 0.3, robot.dof), lower, upper)
    history = np.clip(q + rng.normal(0, 0.02, (3, robot.dof)), lower, upper)
    return sample_at(problem.reference, problem.targets, 3, history, problem.dt), q
