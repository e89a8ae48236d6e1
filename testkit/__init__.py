"""What the tests, the benchmarks (bench/) and the tools (tools/) share; never part of the extension.

    scenes          tiny scenes built in code (SceneBuilder) and their analytic answers
    checks          judging a bake: against an analytic answer, against another bake; independent
                    Monte Carlo estimates
    oracles/        numpy forms of compiled physics, written independently, to check kernels against
    blend           building Blender scenes with the bpy data API (needs bpy)
    addon           looking at what the add-on did in Blender: images, compositor nodes, panels,
                    reports (needs bpy)
    extension       the repository root imported as the extension package ``smbs_caustics``
    cli             ``python -m smbs_addon`` in a subprocess
    cycles          Cycles' render settings for a reference, and reading its EXR files
    conformance     the conformance suite's library: a scene's arrays, its Cycles reference, the judge
    conformance_scenes  the conformance suite's scenes, built with bpy

Installed with the project (``pip install -e .``); nothing here edits sys.path.
"""
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent  # the repository
TEST_DATA = ROOT / "tests" / "data"
SAMPLE_BLENDS = ROOT / "sample_blends"
