"""Your own solver in the loop: the example agrees with the direct solve; a solver that
raises, returns the wrong shape or NaN is reported and changes nothing."""
import numpy as np
import pytest
from conftest import ROOT
from test_solvers import matrix_rows, open_scene

from radtr_addon.solvers import solve
from radtr_addon.solvers.user import UserSolverError

EXAMPLE = f"{ROOT / 'examples' / 'direct_solver.py'}:solve"


def test_example_matches_the_direct_solve():
    s, F = open_scene()
    ours = solve("direct", s, matrix_rows(F))
    theirs = solve("user", s, matrix_rows(F), user=EXAMPLE)
    np.testing.assert_allclose(theirs.B, ours.B, rtol=1e-10)
    assert theirs.converged and theirs.residual < 1e-12


@pytest.mark.parametrize("body, message", [
    ("def f(**kw):\n    raise ValueError('matrix is singular')\n",
     r"raised ValueError: matrix is singular \(bad.py:2\)"),
    ("def f(F, E, **kw):\n    return E[:3]\n", r"returned shape \(3, 3\); expected \(30, 3\)"),
    ("import numpy as np\ndef f(E, **kw):\n    B = E.copy()\n    B[7] = np.nan\n    return B\n",
     "NaN or infinity at patch 7"),
    ("def f(**kw):\n    return 'light'\n", "not an array"),
    ("def g(**kw):\n    pass\n", "has no function 'f'"),
    ("def f(:\n    pass\n", "loading it raised SyntaxError"),
])
def test_bad_user_solvers_are_reported(tmp_path, body, message):
    (tmp_path / "bad.py").write_text(body)
    s, F = open_scene()
    with pytest.raises(UserSolverError, match=message):
        solve("user", s, matrix_rows(F), user=f"{tmp_path / 'bad.py'}:f")


def test_bad_spec():
    s, F = open_scene()
    with pytest.raises(UserSolverError, match="module:function"):
        solve("user", s, matrix_rows(F), user="no_colon")


def test_failing_user_solver_leaves_the_file_as_it_was(cornell, tmp_path):
    from test_addon import small, snapshot

    bpy = cornell
    (tmp_path / "boom.py").write_text("def f(**kw):\n    raise RuntimeError('boom')\n")
    small(bpy, solver="user", user_solver=f"{tmp_path / 'boom.py'}:f", method="embree", rays=16)
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match="user solver .* raised RuntimeError: boom"):
        bpy.ops.radtr.solve()
    assert snapshot(bpy) == before
    small(bpy, solver="user", user_solver=EXAMPLE, method="embree", rays=16)
    assert bpy.ops.radtr.solve() == {"FINISHED"}
