"""The first-start compile shows its progress (issue 31): group k of n, elapsed time, kernels
done, and an estimate scaled from a profile by this machine's measured speed; a line at least
every interval; the warm-up takes a list of kernel groups and stamps the ones it compiled."""

from __future__ import annotations

import json
import time

import numba
import numpy as np
import pytest

from brush_env import kernel_cache
from brush_env.engine import warmup
from brush_env.engine.compile_progress import CompileProgress, format_seconds

#: a made-up profile: group A takes 10 s (kernels f at 2 s, g at 8 s), group B 30 s
PROFILE = {
    "groups": {
        "A": {"seconds": 10.0, "kernels": {"pkg.f#1": 2.0, "pkg.g#1": 8.0}},
        "B": {"seconds": 30.0, "kernels": {"pkg.h#1": 20.0}},
    }
}


class Clock:
    """A clock the test sets (seconds)."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_the_estimate_is_the_profile_scaled_by_the_speed_measured_here():
    clock = Clock()
    lines: list[str] = []
    p = CompileProgress(["A", "B"], PROFILE, lines.append, clock)
    p.start_group(0)
    assert p.estimate() is None  # nothing measured yet
    clock.t = 4.0
    p.kernel_done("pkg.f")  # the profile reached f at 2 s: this machine is 2x slower
    assert p.estimate() == pytest.approx(80.0)  # 2 x (10 + 30) s
    line = p.status()
    assert line.startswith("  compile 1/2: A; 4 s elapsed, 1 of ~3 kernels")
    assert line.endswith("about 76 s left of ~80 s")
    clock.t = 5.0
    p.kernel_done("numba.cpython.builtins.ol_max.<locals>.impl")  # numba's own: not counted
    p.kernel_done("pkg.unknown")  # not in the profile: counted, but no milestone
    assert "2 of ~3 kernels" in p.status()
    assert p.estimate() == pytest.approx(80.0)
    clock.t = 15.0
    p.end_group()  # 15 s for the profile's 10: 1.5x
    assert lines == ["  compile 1/2 done: A (2 kernels in 15 s)"]
    assert p.estimate() == pytest.approx(60.0)
    p.start_group(1)
    clock.t = 35.0
    p.kernel_done("pkg.h")  # (15 + 20) s for (10 + 20) s of the profile
    assert p.estimate() == pytest.approx(40.0 * 35.0 / 30.0)
    assert p.status().endswith("about 12 s left of ~47 s")
    clock.t = 50.0
    assert p.status().endswith("taking longer than the ~47 s estimated")


def test_a_second_signature_of_a_kernel_is_its_own_milestone():
    clock = Clock()
    prof = {"groups": {"A": {"seconds": 10.0, "kernels": {"pkg.f#1": 1.0, "pkg.f#2": 5.0}}}}
    p = CompileProgress(["A"], prof, None, clock)
    p.start_group(0)
    clock.t = 2.0
    p.kernel_done("pkg.f")
    clock.t = 20.0
    p.kernel_done("pkg.f")  # the second compile of f: at 5 s of the profile, 4x slower
    assert p.estimate() == pytest.approx(40.0)
    assert set(p.measured()["groups"]["A"]["kernels"]) == {"pkg.f#1", "pkg.f#2"}


def test_without_a_profile_the_line_says_when_an_estimate_comes():
    p = CompileProgress(["A"], None, None, Clock())
    p.start_group(0)
    p.kernel_done("pkg.f")
    assert p.estimate() is None
    assert p.status().endswith("estimate after the first kernels")


def test_format_seconds():
    assert (format_seconds(45.4), format_seconds(150.0)) == ("45 s", "2.5 min")


def test_the_ticker_prints_a_line_at_least_every_interval():
    lines: list[str] = []
    p = CompileProgress(["slow group"], None, lines.append)
    p.start_group(0)
    with p.ticker(0.02):
        deadline = time.monotonic() + 5.0
        while len(lines) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert len(lines) >= 3
    assert all(ln.startswith("  compile 1/1: slow group; ") for ln in lines)


def _fresh_kernel():
    """A kernel numba has not compiled yet (a new function object each call, no cache)."""

    @numba.njit(cache=False)
    def tiny_sum(x):
        s = 0.0
        for v in x:
            s += v
        return s

    return tiny_sum


def test_warm_up_runs_its_groups_in_order_and_stamps_them(monkeypatch):
    """The warm-up takes a list of groups; the numba compile events become the progress lines
    and the profile it stores (the package's own stamp and cache are left alone)."""
    stored: dict = {}
    monkeypatch.setattr(warmup, "kernels_compiled", lambda *a: True)
    monkeypatch.setattr(warmup, "read_profile", lambda: ({}, ""))
    monkeypatch.setattr(
        warmup, "write_stamp", lambda groups, profile: stored.update(g=groups, p=profile)
    )
    ran: list[str] = []

    def compile_one(tiny) -> None:
        ran.append("a")
        _fresh_kernel()(np.ones(3))

    groups = [
        warmup.KernelGroup("compiles one kernel", compile_one),
        warmup.KernelGroup("compiles nothing", lambda tiny: ran.append("b")),
    ]
    lines: list[str] = []
    warmup.warm_up(groups, notice=lines.append, interval=60.0)
    assert ran == ["a", "b"]
    assert stored["g"] == ["compiles one kernel", "compiles nothing"]
    assert [ln.split(" (")[0] for ln in lines] == ["  compile 1/2 done: compiles one kernel"]
    kernels = stored["p"]["groups"]["compiles one kernel"]["kernels"]
    assert list(kernels) == [f"{__name__}._fresh_kernel.<locals>.tiny_sum#1"]
    assert "compiles nothing" not in stored["p"]["groups"]  # it measured nothing


def test_the_stamp_names_the_groups_compiled_on_these_sources(tmp_path, monkeypatch):
    monkeypatch.setattr(kernel_cache, "STAMP", tmp_path / "stamp")
    monkeypatch.setattr(kernel_cache, "MACHINE_PROFILE", tmp_path / "profile.json")
    assert not kernel_cache.kernels_compiled()
    kernel_cache.write_stamp(["A"], {"groups": {"A": {"seconds": 80.0, "kernels": {"f#1": 1}}}})
    kernel_cache.write_stamp(["B"])  # a later warm-up of another group keeps A
    assert kernel_cache.kernels_compiled() and kernel_cache.kernels_compiled(["A", "B"])
    assert not kernel_cache.kernels_compiled(["A", "C"])
    assert json.loads((tmp_path / "profile.json").read_text())["groups"]["A"]["seconds"] == 80
    monkeypatch.setattr(kernel_cache, "sources_key", lambda: "edited sources")
    assert not kernel_cache.kernels_compiled(["A"])  # an edit invalidates every group


def test_the_notice_gives_this_machines_last_compile_time(tmp_path, monkeypatch):
    monkeypatch.setattr(kernel_cache, "MACHINE_PROFILE", tmp_path / "profile.json")
    assert "estimate from this machine's speed every 10 s" in kernel_cache.compile_notice()
    (tmp_path / "profile.json").write_text(json.dumps(PROFILE))
    assert "(40 s here last time; progress every 10 s;" in kernel_cache.compile_notice()


def test_the_shipped_profile_names_the_warm_up_groups():
    """The shipped profile was measured with today's groups (else no estimate until a compile
    on the user's machine has measured its own)."""
    prof = json.loads(kernel_cache.SHIPPED_PROFILE.read_text())
    names = {g.name for g in warmup.GROUPS}
    assert set(prof["groups"]) <= names
    assert any(len(g["kernels"]) > 10 for g in prof["groups"].values())


def test_merged_profile_keeps_groups_a_partial_warm_up_did_not_measure():
    old = {"groups": {"A": {"seconds": 10.0, "kernels": {"f#1": 1.0}}}}
    new = {
        "groups": {"A": {"seconds": 0.1, "kernels": {}}, "B": {"seconds": 5, "kernels": {"g#1": 5}}}
    }
    assert warmup.merged_profile(old, new) == {"groups": {**old["groups"], "B": new["groups"]["B"]}}


def test_the_line_names_the_innermost_kernel_being_compiled():
    p = CompileProgress(["A"], None, None, Clock())
    p.start_group(0)
    p.kernel_started("brush_env.engine.step.step_bristles")
    p.kernel_started("brush_env.engine.contact.tip_load")
    assert "; now engine.contact.tip_load;" in p.status()
    p.kernel_done("brush_env.engine.contact.tip_load")
    assert "; now engine.step.step_bristles;" in p.status()


def test_edited_engine_sources_purge_the_cached_kernels_once(tmp_path, monkeypatch):
    """A cached caller keeps a changed callee's old code (numba checks only the caller's own
    file), so an edit to any engine source deletes every cached engine kernel, beside the sources
    and under NUMBA_CACHE_DIR, and stamps the sources; unchanged sources delete nothing."""
    engine = tmp_path / "src" / "engine"
    (engine / "__pycache__").mkdir(parents=True)
    (engine / "kernels.py").write_text("x = 1\n")
    user = tmp_path / "numba_cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(user))
    monkeypatch.setattr(kernel_cache, "ENGINE", engine)
    monkeypatch.setattr(kernel_cache, "STAMP", engine / "__pycache__" / "stamp")
    beside, elsewhere = kernel_cache.engine_cache_dirs()
    assert beside == engine / "__pycache__" and elsewhere.parent == user
    # the directory numba itself picks for a source file there (its user-provided locator)
    from numba.core.caching import UserProvidedCacheLocator

    assert elsewhere.name == UserProvidedCacheLocator.get_suitable_cache_subpath(
        str(engine / "kernels.py")
    )
    elsewhere.mkdir(parents=True)
    cached = [beside / "kernels.f-3.py311.nbi", beside / "kernels.f-3.py311.1.nbc"]
    cached.append(elsewhere / "kernels.g-9.py311.nbi")
    for p in cached:
        p.write_bytes(b"old machine code")
    (beside / "kernels.cpython-311.pyc").write_bytes(b"not numba's")
    assert kernel_cache.purge_stale_kernels() == 3  # no stamp yet: the cache's sources unknown
    assert not any(p.exists() for p in cached)
    assert (beside / "kernels.cpython-311.pyc").exists()
    for p in cached:
        p.write_bytes(b"compiled on these sources")
    assert kernel_cache.purge_stale_kernels() == 0  # stamped: kept
    assert all(p.exists() for p in cached)
    (engine / "kernels.py").write_text("x = 2\n")  # an edit
    assert kernel_cache.purge_stale_kernels() == 3
    assert not any(p.exists() for p in cached)


def test_a_run_compiles_only_the_groups_its_level_uses():
    """A command compiles the kernel groups of its settings (``warmup.groups_for``): the
    reference experiment's default (one sweep, BDF2) neither the coupled solve nor the reduced
    model; each level's groups are the warm-up's own (so ``brush-env warmup`` covers them)."""
    from brush_env.engine import SimSettings
    from brush_env.engine.fidelity import level_settings, load_fidelity

    w = warmup
    assert w.groups_for(SimSettings()) == (w.SETUP, w.STEP["bdf2"])
    assert w.groups_for(SimSettings(integrator="euler")) == (w.SETUP, w.STEP["euler"])
    # a coupled level steps only by the coupled kernels: no one-sweep step beside them
    balanced = level_settings(load_fidelity("balanced"))
    assert w.groups_for(balanced) == (w.SETUP, w.COUPLED)
    assert w.groups_for(balanced, follow=True) == (w.SETUP, w.FOLLOW_COUPLED)
    assert w.groups_for(level_settings(load_fidelity("fast"))) == (w.SETUP, w.REDUCED["table"])
    assert w.groups_for(level_settings(load_fidelity("reduced"))) == (w.SETUP, w.REDUCED["prb"])
    # the experiments step only by follow: their first start compiles no step kernel
    assert w.groups_for(SimSettings(), follow=True) == (w.SETUP, w.FOLLOW["bdf2"])
    covered = {name for g in w.GROUPS for name in (g.name, *g.covers)}
    for level in ("coarse", "fast", "reduced", "balanced", "paper", "reference"):
        for follow in (False, True):
            groups = w.groups_for(level_settings(load_fidelity(level)), follow=follow)
            assert {g.name for g in groups} <= covered
    assert w.groups_for(SimSettings(model="my_model")) == w.GROUPS


def test_a_full_warm_up_counts_for_the_follow_groups(monkeypatch):
    """``brush-env warmup`` steps by ``step`` and by ``follow``: its stamp names the follow-only
    groups too, so the reference experiment does not announce a compile after it."""
    written = {}
    monkeypatch.setattr(warmup, "write_stamp", lambda names, profile: written.update(n=names))
    monkeypatch.setattr(warmup, "_Tiny", lambda: None)
    monkeypatch.setattr(warmup, "kernels_compiled", lambda *a: True)
    fake = warmup.KernelGroup(warmup.STEP["bdf2"].name, lambda t: None, warmup.STEP["bdf2"].covers)
    warmup.warm_up((fake,))
    assert written["n"] == [warmup.STEP["bdf2"].name, warmup.FOLLOW["bdf2"].name]


def test_a_numba_cache_dir_is_purged_by_its_own_stamp(tmp_path, monkeypatch):
    """A process without NUMBA_CACHE_DIR purges and stamps the cache beside the sources; a
    later process with NUMBA_CACHE_DIR set must still purge that directory's stale kernels (its
    own stamp: the one beside the sources once said "current" for it too, and a benchmark ran a
    caller's stale machine code after an edit to its callee's module)."""
    engine = tmp_path / "src" / "engine"
    (engine / "__pycache__").mkdir(parents=True)
    (engine / "kernels.py").write_text("x = 1\n")
    monkeypatch.setattr(kernel_cache, "ENGINE", engine)
    monkeypatch.setattr(kernel_cache, "STAMP", engine / "__pycache__" / "stamp")
    user = tmp_path / "numba_cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(user))
    elsewhere = kernel_cache.engine_cache_dirs()[-1]
    elsewhere.mkdir(parents=True)
    assert kernel_cache.purge_stale_kernels() == 0  # both empty, now both stamped
    (elsewhere / "kernels.g-9.py311.nbi").write_bytes(b"compiled on x = 1")
    (engine / "kernels.py").write_text("x = 2\n")  # an edit, then a run without the variable
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert kernel_cache.purge_stale_kernels() == 0  # nothing cached beside the sources
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(user))  # a run with it: its own stamp is stale
    assert kernel_cache.purge_stale_kernels() == 1
    assert not (elsewhere / "kernels.g-9.py311.nbi").exists()
    assert kernel_cache.purge_stale_kernels() == 0
