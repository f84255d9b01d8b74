"""``bench cost``: the callgrind reader and the split into parts, on a call graph written here
(no valgrind in the tests), and the symbol names of numba's mangled kernels."""

from __future__ import annotations

import pytest

from brush_env.bench import cost as C

# a callgrind file as callgrind writes it (name compression, one event): step_bristles calls
# newton_solve, which calls the Jacobian, the factorisation, the solve, the tip load and the
# element; the coupling kernel is called by step_bristles; python's frame calls step_bristles
CALLGRIND = """\
version: 1
creator: callgrind-3.19.0
events: Ir
fl=(1) ???
fn=(1) python_frame
0 1000
cfn=(2) 0x00000000000000a0
calls=1 0
0 98000
fn=(2)
0 500
cfn=(3) 0x00000000000000b0
calls=10 0
0 90000
cfn=(8) 0x0000000000000100
calls=3 0
0 7500
fn=(3)
0 20000
cfn=(4) 0x00000000000000c0
calls=2 0
0 30000
cfn=(5) 0x00000000000000d0
calls=2 0
0 8000
cfn=(6) 0x00000000000000e0
calls=10 0
0 6000
cfn=(7) 0x00000000000000f0
calls=10 0
0 4000
cfn=(9) 0x0000000000000110
calls=60 0
0 22000
fn=(8)
0 7500
fn=(4)
0 30000
fn=(5)
0 8000
fn=(6)
0 6000
fn=(7)
0 4000
fn=(9)
0 22000
"""
SYMBOLS = {
    "0xa0": "step.step_bristles",
    "0xb0": "newton.newton_solve",
    "0xc0": "residual._jacobian_chain",
    "0xd0": "_kernels.block_factor_head",
    "0xe0": "_kernels.block_solve",
    "0xf0": "contact.tip_load",
    "0x100": "coupling._solve_group",
    "0x110": "_kernels._element_mid",
}


def test_split_sums_to_the_total_and_names_each_part(tmp_path):
    f = tmp_path / "callgrind.out"
    f.write_text(CALLGRIND)
    self_cost, arcs = C.read_callgrind(f)
    assert sum(self_cost.values()) == 99000  # every function's own cost, as written
    assert arcs[("0x00000000000000b0", "0x00000000000000c0")] == 30000
    parts = C.split(self_cost, arcs, SYMBOLS)
    assert parts["Jacobian"] == 30000
    assert parts["factorisation"] == 8000
    assert parts["solve"] == 6000
    assert parts["contact"] == 4000
    assert parts["residual"] == 22000
    assert parts["shaft contact"] == parts["predictor"] == 0
    assert parts["Newton's own"] == 20000
    assert parts["coupling"] == 7500
    assert parts["sweep and step"] == 500
    assert parts["outside the bristle kernel"] == 1000
    assert sum(parts.values()) == 99000  # the parts add up to the whole run


def test_functions_own_and_inclusive_cost(tmp_path):
    f = tmp_path / "callgrind.out"
    f.write_text(CALLGRIND)
    self_cost, arcs = C.read_callgrind(f)
    fn = C.functions(self_cost, arcs, SYMBOLS)
    # own cost as written; with callees: own + what its calls cost (callgrind's inclusive arcs)
    assert fn["newton.newton_solve"] == {"self": 20000, "inclusive": 90000}
    assert fn["step.step_bristles"] == {"self": 500, "inclusive": 98000}
    assert fn["python_frame"]["inclusive"] == 99000
    assert sum(v["self"] for v in fn.values()) == 99000
    r = {"bodies": 6, "sweeps": 1, "steps": 10, "functions": fn}
    rows = C.function_rows(r, 2, 3)  # per bristle-step: 10 steps x 2 bristles
    assert rows[0]["inclusive_per_bristle_step"] == 98000 / 20  # the step kernel
    assert rows[1]["inclusive_per_bristle_step"] == 0  # no broad phase in this graph
    assert [x["function"] for x in rows[2:]] == [
        "residual._jacobian_chain",
        "_kernels._element_mid",
        "newton.newton_solve",
    ]  # the three largest own costs, largest first


@pytest.mark.parametrize(
    "mangled, short",
    [
        (
            "_ZN9brush_env6engine6sweeps14sweep_bristlesB3v41B40c8tJTIeFIjxB2IKSgI4CrvSCKgE5Model",
            "sweeps.sweep_bristles",
        ),
        (
            "_ZN9brush_env6engine8_kernels3lu6B4v201B36c8tJTIeFIjxE5ArrayIdLi2E1C7mutabl",
            "_kernels.lu6",
        ),
        ("cfunc._ZN9brush_env6engine4step13step_bristlesB3v35B40c8tE5", "cfunc.step.step_bristles"),
        ("atan2", "atan2"),
    ],
)
def test_short_name_of_numba_symbols(mangled, short):
    assert C.short_name(mangled) == short


def test_bench_steps_window_measures_only_its_steps(capsys):
    """``bench steps --window START COUNT`` (bench cost's measured steps) reports COUNT steps from
    START; a window outside the motion names the flag, its value and the range."""
    import json

    from brush_env import cli

    assert (
        cli.main(["bench", "steps", "--scene", "flat_plate", "--window", "900", "3", "--json"]) == 0
    )
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (row["first_step"], row["steps"]) == (900, 3)
    assert row["newton_iterations"] > 0  # mid-stroke every bristle is in contact
    assert cli.main(["bench", "steps", "--scene", "flat_plate", "--window", "1", "3"]) == 2
    err = capsys.readouterr().err
    assert "--window 1 3" in err and "start >= 2" in err


def test_bench_steps_runs_the_paper_turn(capsys):
    """``bench steps --motion turn`` steps bench element's turn on the plate at 1 ms: t = 0 ..
    7.233 s (0.5 s press, 0.25 s hold, the circle with its ramps), whatever ``--scene`` says."""
    import json

    from brush_env import cli

    args = ["bench", "steps", "--motion", "turn", "--fidelity", "coarse", "--window", "7230", "3"]
    assert cli.main(args + ["--json"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (row["scene"], row["motion"], row["steps"]) == ("flat_plate", "turn", 3)
    assert cli.main(args[:-2] + ["7233", "3"]) == 2  # past the turn's last step
    assert "start + count <= 7234" in capsys.readouterr().err
