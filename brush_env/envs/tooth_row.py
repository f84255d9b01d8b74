"""``brush_env/ToothRow-v0``: brush the buccal side of a row of teeth without hurting the gum.

Description
-----------
FlatPlate-v0's task on teeth: the same brush, engine, actions, observation layout and reward
terms, on the tooth-row scene (``configs/scenes/tooth_row.toml``: four maxillary posterior crowns
of Wheeler's dimensions with 0.7 mm interdental gaps, buccal surfaces facing the brush, the gum
below the cemento-enamel junction; ``brush_env.geometry.teeth``).  Contact with the crowns and the
gum uses signed distance fields (``brush_env.engine.sdf``).  The crowns' buccal height of contour
is the plane z = 0 of FlatPlate-v0's plate, so the frames, the touch height ``z_t`` and the
workspace read the same.  The reference policy is a horizontal scrub
(``brush_env.envs.reference.ScrubReference``).

Differences from FlatPlate-v0
-----------------------------
* **Coverage** is measured on the crowns (``brush_env.coverage.SurfaceCoverage``):
  area-weighted samples above the CEJ, cleaned when an effective tip's contact point passes
  within ``clean_radius``.  The coverage term and ``info["coverage"]`` count the area a brush
  on the buccal side can reach (buccal, occlusal and interproximal regions);
  ``info["coverage_regions"]`` gives each region's cleaned fraction (lingual included, for
  reference: it stays 0), ``info["coverage_teeth"]`` each tooth's.  The observation's
  ``coverage_map`` is the buccal view (x along the row, y up the crowns) in
  ``coarse_map_size`` blocks.  ``patch_size`` and ``cell_size`` are not used.
* **Gum force**: reward term ``gum_force = - gum_force_weight * integral of max(0, F_gum -
  gum_force_limit) dt`` with ``F_gum`` the normal force of the tips whose deepest contact is the
  gum; ``info["gum_force"]`` (last engine step), ``info["peak_gum_force"]`` (over the step).
  The 1 N default is our choice, not a clinical threshold: a quarter of the 4 N total limit,
  because gingival abrasion comes before enamel wear (docs/env.md).
* ``reset(options={"plate_offset": ...})`` shifts the tooth row as it shifts the plate.
* Rendering (``rgb_array``/``human``): a 3-D view of the crowns coloured by coverage with the
  bristles, and the buccal coverage map (matplotlib; ~0.5 s a frame).

Everything else (action space, observation blocks, total and per-tip force terms, termination,
arguments) is as documented in ``brush_env.envs.flat_plate``; the defaults of this env are in
``configs/envs/tooth_row.toml``.
"""

from __future__ import annotations

import os

import numpy as np

from brush_env.coverage import crown_samples, gum_force
from brush_env.engine import ConfigError
from brush_env.engine.scene import tooth_surfaces

from .config import EnvConfig
from .flat_plate import BrushEnv

__all__ = ["ToothRowEnv"]

REWARD_TERMS = ("coverage", "total_force", "tip_force", "gum_force", "termination")


class ToothRowEnv(BrushEnv):
    """Brush the buccal side of a tooth row (see the module docstring)."""

    reference_motion = "scrub"

    def __init__(
        self,
        config: str | os.PathLike | EnvConfig | None = "tooth_row",
        render_mode: str | None = None,
        **overrides,
    ):
        super().__init__(config, render_mode, **overrides)

    def _teeth(self):
        crowns = tooth_surfaces(self.scene)
        if not crowns:
            raise ConfigError(
                f"scene = {self.config.scene!r} has no tooth surface (a 'tooth_row' or a 'mesh' "
                "surface labelled tooth:...): ToothRow-v0 needs teeth "
                "(configs/scenes/tooth_row.toml)"
            )
        return crowns

    def _surface_height(self, scene) -> float:
        """z [mm] of the crowns' buccal plane: their highest point (0 for the procedural row)."""
        return float(max(s.vertices[:, 2].max() for s in self._teeth()))

    def _make_coverage(self):
        return crown_samples(self._teeth(), self.config.clean_radius, self.config.coarse_map_size)

    def _get_rew(self, sim: dict) -> dict[str, float]:
        terms = super()._get_rew(sim)
        gum = -self.config.gum_force_weight * sim["gum_int"]
        return {k: terms[k] if k != "gum_force" else gum for k in REWARD_TERMS}

    def _reset_info(self) -> dict:
        info = super()._reset_info()
        info["coverage_regions"] = self.coverage.by_region()
        info["coverage_teeth"] = self.coverage.by_tooth()
        return info

    def _get_info(self, sim: dict, terms: dict) -> dict:
        info = super()._get_info(sim, terms)
        info.pop("cells_cleaned", None)
        out = self._last
        info["area_cleaned"] = self.coverage.count
        info["coverage_regions"] = self.coverage.by_region()
        info["coverage_teeth"] = self.coverage.by_tooth()
        info["gum_force"] = gum_force(out, self._gum)
        info["peak_gum_force"] = sim["peak_gum"]
        return info

    def _frame(self) -> np.ndarray:
        from brush_env.viz.tooth_row import render_tooth_row

        from .rendering import FrameWindow

        if self._renderer is None:  # the window of human mode
            self._renderer = FrameWindow(self.config.render_height, 2 * self.config.render_height)
        if not self._started:
            raise RuntimeError("call reset() before render()")
        out, st = self._last, self.sim.state
        assert st is not None  # reset() ran
        m = self.sim.model
        roots = self._p + m.root_p @ self._R.T
        chains = np.concatenate(
            [roots[:, None], st.pos[self._chain_idx], out.tip_pos[:, None]], axis=1
        )
        return render_tooth_row(
            self._teeth(),
            self.coverage,
            chains,
            out.tip_normal_force,
            self.config.render_height,
            title=(
                f"t = {out.time:.2f} s   coverage {100 * self.coverage.fraction:.1f} %   "
                f"F = {self._total_force:.2f} N (limit {self.config.total_force_limit:g} N)"
            ),
        )
