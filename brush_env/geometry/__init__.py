"""brush_env.geometry: the shapes scenes are made of, beside the engine (issue 27).

``teeth`` (the procedural tooth row: Wheeler crown meshes, the gum capsule, surface samples by
region), ``meshes`` (mesh files through trimesh, with their checks) and ``sdf_bake`` (closed
meshes baked into narrow-band signed-distance grids, and their disk cache).  The engine imports
this package (``engine.scene`` builds surfaces from it); it imports only the engine's leaf
modules (``engine.checks`` for errors, ``engine.sdf`` for the grid it bakes into), never the
envs, experiments or anything above them.
"""

# The engine's package initialises first: ``engine.scene`` imports ``sdf_bake``, which imports the
# engine's leaf modules; importing a geometry module first (``from brush_env.geometry.sdf_bake
# import bake_mesh``) would otherwise meet its own half-initialised module through the engine.
import brush_env.engine  # noqa: E402,F401  (import order, see above)
