"""A bake, from a Scene to a BakeResult: its settings, the plan (what the scene calls for: plan,
pilots), auto's choice per light (auto), the passes per batch (passes; light_tracing and walking
for the two pipelines), the stop rule (stop), the result and error bar (result, convergence),
equal-time comparisons (compare), compiling ahead (prepare). bake.bake is the entry point;
engine runs one bake of a fixed pipeline. Imports the layers below.
"""
