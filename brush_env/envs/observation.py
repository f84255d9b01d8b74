"""Observation types: the named, scaled blocks of BrushEnv's observation, as a Box or a Dict.

``ObservationLayout`` is the single source of the layout: block names, shapes, bounds, units and
scales, in order.  ``BoxObservation`` concatenates the blocks into one float32 vector (C order);
``DictObservation`` gives one float32 Box per block.  Every value is divided by its scale and
clipped to its block's bounds, so observations always lie in the space (the clip only bites in
extreme states, e.g. the step that leaves the workspace).

Frames: "TCP frame" is the tool frame (z along the bristles, towards the plate); "base frame" is
the robot base (z up).  Positions are relative to the *nominal* patch centre on the nominal plate
surface; the actual plate is offset by the (unobserved) ``plate_offset`` drawn at reset.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numba import njit

from .config import EnvConfig

__all__ = [
    "Block",
    "ObservationLayout",
    "BoxObservation",
    "DictObservation",
    "make_observation_type",
]


@dataclass(frozen=True)
class Block:
    """One named part of the observation: shape, bounds (after scaling), unit and scaling."""

    name: str
    shape: tuple
    low: float
    high: float
    unit: str
    scaling: str

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))


def _tip_blocks(cfg: EnvConfig, nb: int, L: float) -> tuple[Block, ...]:
    """The ``nb`` tips: deflection (scaled by the longest bristle ``L`` [mm]), velocity, plate
    normal force and contact flag."""
    return (
        Block(
            "tip_deflection",
            (nb, 3),
            -2.0,
            2.0,
            "mm / L",
            f"tip minus its rest position, TCP frame, / L = {L:g} mm",
        ),
        Block(
            "tip_velocity",
            (nb, 3),
            -10.0,
            10.0,
            "mm/s / v_tip",
            "tip velocity relative to the rigidly moving head, TCP frame, "
            f"/ tip_velocity_scale = {cfg.tip_velocity_scale:g} mm/s",
        ),
        Block(
            "tip_normal_force",
            (nb,),
            0.0,
            10.0,
            "N / f_tip",
            f"plate normal force on each tip / tip_force_limit = {cfg.tip_force_limit:g} N",
        ),
        Block("tip_contact", (nb,), 0.0, 1.0, "flag", "1 if the tip touches the plate"),
    )


def _tcp_blocks(cfg: EnvConfig, h: float) -> tuple[Block, ...]:
    """The TCP: force and moment on the brush, position (height scale ``h`` [mm]), orientation
    and the last commanded twist."""
    return (
        Block(
            "tcp_force",
            (3,),
            -5.0,
            5.0,
            "N / F_s",
            f"force the TCP applies to the brush, TCP frame, / force_scale = {cfg.force_scale:g} N",
        ),
        Block(
            "tcp_moment",
            (3,),
            -5.0,
            5.0,
            "N mm / M_s",
            f"moment about the TCP, TCP frame, / moment_scale = {cfg.moment_scale:g} N mm",
        ),
        Block(
            "tcp_position",
            (3,),
            -1.5,
            1.5,
            "mm / ws",
            "TCP x, y about the nominal patch centre and height z - z_t above touching, "
            f"base frame, / ({cfg.workspace_xy:g}, {cfg.workspace_xy:g}, {h:g}) mm",
        ),
        Block(
            "tcp_orientation",
            (6,),
            -1.0,
            1.0,
            "-",
            "first two columns of the TCP rotation matrix (TCP x and y axes in the base frame)",
        ),
        Block(
            "tcp_twist",
            (6,),
            -1.0,
            1.0,
            "-",
            "commanded TCP velocity (v, w), base frame, / (max_linear_speed, "
            "max_angular_speed): the last action",
        ),
    )


def _task_blocks(m: int) -> tuple[Block, ...]:
    """The task: coverage fraction, the ``m`` x ``m`` coarse coverage map and time remaining."""
    return (
        Block("coverage_fraction", (1,), 0.0, 1.0, "-", "fraction of patch cells cleaned"),
        Block(
            "coverage_map",
            (m, m),
            0.0,
            1.0,
            "-",
            f"fraction cleaned per block of the {m} x {m} grid over the patch; row i runs "
            "along +y, column j along +x",
        ),
        Block("time_remaining", (1,), 0.0, 1.0, "-", "1 - elapsed steps / max_episode_steps"),
    )


def _slices(blocks) -> dict[str, slice]:
    """Each block's slice of the flat (Box) observation, in order."""
    slices, start = {}, 0
    for b in blocks:
        slices[b.name] = slice(start, start + b.size)
        start += b.size
    return slices


#: the blocks ``_fill`` writes, in the order of its offsets (``ObservationLayout._off``)
FILLED = (
    "tip_deflection",
    "tip_velocity",
    "tip_normal_force",
    "tip_contact",
    "tcp_force",
    "tcp_moment",
    "tcp_position",
    "tcp_orientation",
    "tcp_twist",
    "coverage_fraction",
    "coverage_map",
    "time_remaining",
)
#: ``_fill``'s inputs: the tips ((nb, 3) [mm], [mm/s], rest (nb, 3) [mm] TCP frame, normal force
#: (nb,) [N], contact (nb,) bool) and the TCP (p [mm], R, v [mm/s], w [rad/s], force [N] and
#: moment [N mm] in the TCP frame, p_obs [mm] about the nominal patch centre)
TipInput = namedtuple("TipInput", ["pos", "vel", "rest", "fn", "contact"])
TcpInput = namedtuple("TcpInput", ["p", "R", "v", "w", "force", "moment", "p_obs"])


@njit(cache=True, fastmath=False)
def _fill(out, off, tip, tcp, cmap, sc, task, low, high):
    """out (size,) float32 <- ``ObservationLayout.flat``'s vector: each value scaled (sc: 1/L,
    1/tip_velocity_scale, 1/tip_force_limit, 1/force_scale, 1/moment_scale, touch_height
    [mm], position_scale (3,) [mm], v_max (3,), w_max (3,)), clipped to [low, high] in double
    precision and then cast; off: each block's start (``FILLED``); task: (coverage fraction,
    time remaining)."""
    R, p, v, w = tcp.R, tcp.p, tcp.v, tcp.w
    raw = np.empty(out.shape[0])
    nb = tip.pos.shape[0]
    rel = np.empty(3)
    c = np.empty(3)
    for i in range(nb):
        for a in range(3):
            rel[a] = tip.pos[i, a] - p[a]
        # w x rel: the TCP's rotation carries the tip along
        c[0] = w[1] * rel[2] - w[2] * rel[1]
        c[1] = w[2] * rel[0] - w[0] * rel[2]
        c[2] = w[0] * rel[1] - w[1] * rel[0]
        for b in range(3):
            d = rel[0] * R[0, b] + rel[1] * R[1, b] + rel[2] * R[2, b]  # (rel R)_b: TCP frame
            raw[off[0] + 3 * i + b] = (d - tip.rest[i, b]) * sc[0]
            u = (
                (tip.vel[i, 0] - v[0] - c[0]) * R[0, b]
                + (tip.vel[i, 1] - v[1] - c[1]) * R[1, b]
                + (tip.vel[i, 2] - v[2] - c[2]) * R[2, b]
            )
            raw[off[1] + 3 * i + b] = u * sc[1]
        raw[off[2] + i] = tip.fn[i] * sc[2]
        raw[off[3] + i] = 1.0 if tip.contact[i] else 0.0
    for a in range(3):
        raw[off[4] + a] = tcp.force[a] * sc[3]
        raw[off[5] + a] = tcp.moment[a] * sc[4]
        q = tcp.p_obs[a] - (sc[5] if a == 2 else 0.0)
        raw[off[6] + a] = q / sc[6 + a]
        raw[off[7] + a] = R[a, 0]
        raw[off[7] + 3 + a] = R[a, 1]
        raw[off[8] + a] = v[a] / sc[9 + a]
        raw[off[8] + 3 + a] = w[a] / sc[12 + a]
    raw[off[9]] = task[0]
    m = cmap.shape[0]
    for i in range(m):
        for j in range(cmap.shape[1]):
            raw[off[10] + i * cmap.shape[1] + j] = cmap[i, j]
    raw[off[11]] = task[1]
    for k in range(out.shape[0]):
        x = raw[k]
        if x < low[k]:
            x = low[k]
        elif x > high[k]:
            x = high[k]
        out[k] = x  # a NaN stays NaN (as np.clip)


class ObservationLayout:
    """Blocks of the observation for a brush of ``n_bristles`` tips (see the env docstring).

    ``max_length`` L [mm] scales the tip deflections; ``touch_height`` z_t [mm] (default L) is
    the TCP height at which the lowest tip sphere touches the nominal plate (``BrushEnv`` passes
    L + R).  ``values(...)`` turns physical quantities into the scaled, clipped blocks; ``block(obs,
    name)`` reads a block back from a Box or Dict observation; ``tcp_pose`` and
    ``elapsed_steps`` undo the scaling of the blocks a scripted policy needs.
    """

    def __init__(
        self, cfg: EnvConfig, n_bristles: int, max_length: float, touch_height: float | None = None
    ):
        nb, m = int(n_bristles), cfg.coarse_map_size
        self.cfg = cfg
        self.n_bristles = nb
        self.max_length = float(max_length)
        #: TCP height [mm] at which the lowest tip sphere touches the nominal plate (L + R)
        self.touch_height = float(max_length if touch_height is None else touch_height)
        h = max(abs(cfg.workspace_height[0]), abs(cfg.workspace_height[1]))
        self.position_scale = np.array([cfg.workspace_xy, cfg.workspace_xy, h])
        self.v_max = np.asarray(cfg.max_linear_speed, float)
        self.w_max = np.asarray(cfg.max_angular_speed, float)
        self.blocks = _tip_blocks(cfg, nb, self.max_length) + _tcp_blocks(cfg, h) + _task_blocks(m)
        self.index = {b.name: b for b in self.blocks}
        self.slices = _slices(self.blocks)
        self.size = sum(b.size for b in self.blocks)
        self.low = np.concatenate([np.full(b.size, b.low, np.float32) for b in self.blocks])
        self.high = np.concatenate([np.full(b.size, b.high, np.float32) for b in self.blocks])
        # what ``_fill`` reads: each block's start (FILLED's order) and the scales
        self._off = np.array([self.slices[n].start for n in FILLED], np.int64)
        self._scale = np.concatenate(
            [
                [
                    1.0 / self.max_length,
                    1.0 / cfg.tip_velocity_scale,
                    1.0 / cfg.tip_force_limit,
                    1.0 / cfg.force_scale,
                    1.0 / cfg.moment_scale,
                    self.touch_height,
                ],
                self.position_scale,
                self.v_max,
                self.w_max,
            ]
        )

    # ------------------------------------------------------------------ physical -> scaled
    def values(self, **physical) -> dict[str, np.ndarray]:
        """``flat``'s blocks by name (each (shape) float32, a view of one flat vector)."""
        return self.split(self.flat(**physical))

    def split(self, flat: np.ndarray) -> dict[str, np.ndarray]:
        """The blocks of a flat observation by name (views, each of its block's shape)."""
        return {b.name: flat[self.slices[b.name]].reshape(b.shape) for b in self.blocks}

    def flat(
        self,
        *,
        p,
        R,
        v,
        w,
        tip_pos,
        tip_vel,
        rest_tips,
        tip_force,
        tip_contact,
        tcp_force_tcp,
        tcp_moment_tcp,
        p_obs,
        coverage_fraction,
        coverage_map,
        time_remaining,
    ) -> np.ndarray:
        """The scaled, clipped observation (size,) float32 in layout order from physical values
        (mm, s, N; base frame unless stated).  ``p, R``: TCP pose (engine frame); ``v, w``:
        commanded twist; ``rest_tips``: (nb, 3) tip rest positions in the TCP frame; ``p_obs``:
        TCP position about the nominal patch centre with z above the nominal plate.

        One compiled pass (``_fill``): every env step calls it, and numpy's block by block
        writes cost ~25-50 us of a ~700 us env step at the level ``fast``."""
        out = np.empty(self.size, np.float32)
        _fill(
            out,
            self._off,
            TipInput(tip_pos, tip_vel, rest_tips, tip_force, tip_contact),
            TcpInput(p, R, v, w, tcp_force_tcp, tcp_moment_tcp, p_obs),
            np.asarray(coverage_map, float),
            self._scale,
            (float(coverage_fraction), float(time_remaining)),
            self.low,
            self.high,
        )
        return out

    # ------------------------------------------------------------------ scaled -> physical
    def block(self, obs, name: str) -> np.ndarray:
        """Block ``name`` of a Box (flat, or batched (n, size)) or Dict observation (scaled)."""
        if isinstance(obs, dict):
            return np.asarray(obs[name])
        obs = np.asarray(obs)
        b = self.index[name]
        return obs[..., self.slices[name]].reshape(obs.shape[:-1] + b.shape)

    def tcp_pose(self, obs) -> tuple[np.ndarray, np.ndarray]:
        """TCP position [mm] (about the nominal patch centre; z above the nominal plate) and
        rotation matrix from an observation (float32 precision: ~1e-5 mm, ~1e-7 rad)."""
        pos = self.block(obs, "tcp_position").astype(float) * self.position_scale
        pos[..., 2] += self.touch_height
        c = self.block(obs, "tcp_orientation").astype(float)
        x = c[..., 0:3] / np.linalg.norm(c[..., 0:3], axis=-1, keepdims=True)
        y = c[..., 3:6] - x * np.sum(x * c[..., 3:6], axis=-1, keepdims=True)
        y /= np.linalg.norm(y, axis=-1, keepdims=True)
        z = np.cross(x, y)
        return pos, np.stack([x, y, z], axis=-1)

    def elapsed_steps(self, obs, horizon: int) -> np.ndarray:
        """Control steps since reset, recovered from ``time_remaining`` (exact for horizons up
        to ~10^6 steps)."""
        r = self.block(obs, "time_remaining").astype(float)[..., 0]
        return np.rint((1.0 - r) * horizon).astype(int)

    def table(self) -> str:
        """Markdown table of the layout (index range, name, shape, bounds, unit, scaling)."""
        rows = [
            "| Index | Block | Shape | Bounds | Unit | Meaning and scaling |",
            "|---|---|---|---|---|---|",
        ]
        for b in self.blocks:
            s = self.slices[b.name]
            rows.append(
                f"| {s.start}-{s.stop - 1} | `{b.name}` | {b.shape} | "
                f"[{b.low:g}, {b.high:g}] | {b.unit} | {b.scaling} |"
            )
        return "\n".join(rows)


class BoxObservation:
    """One flat float32 Box: the blocks concatenated in layout order (C order within a block)."""

    def __init__(self, layout: ObservationLayout):
        self.layout = layout

    def space(self) -> spaces.Box:
        lay = self.layout
        return spaces.Box(lay.low.copy(), lay.high.copy(), shape=(lay.size,), dtype=np.float32)

    def observe(self, flat: np.ndarray) -> np.ndarray:
        """The observation from ``ObservationLayout.flat``'s vector: that vector."""
        return flat


class DictObservation:
    """A ``spaces.Dict`` of float32 Boxes, one per block, keyed by block name."""

    def __init__(self, layout: ObservationLayout):
        self.layout = layout

    def space(self) -> spaces.Dict:
        return spaces.Dict(
            {
                b.name: spaces.Box(b.low, b.high, shape=b.shape, dtype=np.float32)
                for b in self.layout.blocks
            }
        )

    def observe(self, flat: np.ndarray) -> dict[str, np.ndarray]:
        """The observation from ``ObservationLayout.flat``'s vector: its blocks by name."""
        return self.layout.split(flat)


def make_observation_type(cfg: EnvConfig, layout: ObservationLayout):
    return (BoxObservation if cfg.observation_mode == "box" else DictObservation)(layout)
