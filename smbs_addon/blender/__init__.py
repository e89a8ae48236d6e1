"""The Blender boundary: the one package that imports bpy. export.py's ``export_scene`` turns a bpy
scene into a ``Scene`` through nodes.py, bsdfs.py, bump_nodes.py, materials.py, meshes.py,
cycles_passes.py, lights.py, camera.py, world.py and visibility.py; open_blend.py opens a .blend file
for the command line; composite.py puts a baked layer into the scene's compositor."""
