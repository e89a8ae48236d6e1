"""The compiled per-lane loops (numba, nogil), each a loop over lanes that casts its own rays
through embree: the Newton step (newton), a chain from ray hits (chain), SMBS's large mutation
(large_mutation), the walk (walk), the Bernoulli trials (trials), photons (photons), eye paths
(eye), gathering (gather), the seen hand-off (handoff), the film's splats (film); records holds the
record layouts and codes they share with their callers, by name. Imports core, scene and shading.
"""
