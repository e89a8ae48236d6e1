"""The scene as numpy arrays, the contract between the Blender export and the render core.

arrays (Scene, Camera, save/load), constants (material kinds, light types, Ray Visibility bits,
limits), validate (every check, each naming its object), builder (a Scene piece by piece: the
export, the tests, the CLI), geometry (triangle areas and points, a vertex's differential
geometry), bump (a Bump node's height field as shading normals), light_paths (Cycles' Light Paths
bounce limits). Imports core only.
"""
