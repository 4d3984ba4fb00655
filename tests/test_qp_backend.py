"""The QP backend's qpsolvers calls: an interrupt inside a solver reaches the program as itself."""

from __future__ import annotations

import clarabel
import numpy as np
import pytest
import scipy.sparse as sp

from hlik.solvers.qp_backend import qpsolvers_solve


def _problem() -> dict:
    """min 1/2 |x|^2 - x_0 within [-1, 1]^2 and x_0 + x_1 <= 0.5: x = (0.75, -0.25)."""
    return dict(
        P=sp.eye(2, format="csc"),
        q=np.array([-1.0, 0.0]),
        G=sp.csc_matrix(np.ones((1, 2))),
        h=np.array([0.5]),
        lb=-np.ones(2),
    )


def test_a_small_qp_is_solved():
    x = qpsolvers_solve(**_problem(), ub=np.ones(2), solver="clarabel")
    assert np.allclose(x, [0.75, -0.25], atol=1e-6)


@pytest.mark.parametrize("raised", [KeyboardInterrupt, SystemExit])
def test_ctrl_c_and_sigterm_inside_clarabel_are_raised_as_themselves(monkeypatch, raised):
    """Clarabel's wrapper in qpsolvers turns every exception into a ProblemError: Ctrl-C during the
    whole-take stage printed a traceback instead of "interrupted; nothing written" (field cases)."""

    def interrupted(*args, **kwargs):
        raise raised()

    monkeypatch.setattr(clarabel, "DefaultSolver", interrupted)
    with pytest.raises(raised):
        qpsolvers_solve(**_problem(), ub=np.ones(2), solver="clarabel")


def test_a_solver_that_fails_to_build_is_a_failed_solve(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("panic")

    monkeypatch.setattr(clarabel, "DefaultSolver", broken)
    assert qpsolvers_solve(**_problem(), ub=np.ones(2), solver="clarabel") is None
