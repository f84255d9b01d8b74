"""Planar (side-view) brushing model of one bristle row, built on pymunk (issue 14).

``PlanarBrush`` (``model.py``): a row of the brush as pymunk chains over a surface ``Profile``;
``PlanarSettings``: the pymunk step, mass scaling, solver iterations, friction.  The env
``brush_env/PlanarStroke-v0`` (``brush_env.envs.planar_stroke``) and ``brush-env bench planar``
(``brush_env.bench.planar``: against the 3-D engine) sit above it.  Needs pymunk (the ``env``
extra).
"""

from .model import PlanarBrush, PlanarSettings, Profile, row_bristles

__all__ = ["PlanarBrush", "PlanarSettings", "Profile", "row_bristles"]
