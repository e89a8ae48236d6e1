"""Light transport beside the walks: the light tracer's photons (photons), gathering after diffuse
bounces and the light tracer's eye pass (gather), which paths the photon hand-off takes (handoff),
and how strongly a path focuses (focus). Imports the layers below.
"""
