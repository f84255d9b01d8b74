"""brush_env.geometry: the shapes scenes are made of, beside the engine (issue 27).

``teeth`` (the procedural tooth row: Wheeler crown meshes, the gum capsule, surface samples by
region), ``meshes`` (mesh files through trimesh, with their checks) and ``sdf_bake`` (closed
meshes baked into narrow-band signed-distance grids, and their disk cache).  The engine imports
this package (``engine.scene`` builds surfaces from it); it imports only the engine's leaf
modules (``engine.checks`` for errors, ``engine.sdf`` for the grid it bakes into), never the
envs, experiments or anything above them.
"""
