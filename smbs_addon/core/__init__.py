"""The bottom layer: what every other layer uses and nothing of the renderer itself.

errors (messages that name the object), vec and vec3 (3-vectors over numpy arrays and as tuples in
compiled code), jit (numba's settings and disk cache), embree (embree's C API called from compiled
code), lanes (blocks of lanes over threads), random (named random streams), compiles (what compiling
the kernels costs a bake). Imports nothing of smbs_addon.
"""
