"""The Flamenco job type (farm/flamenco/smbs_caustics.js, docs/farm.md): compiled with node against a
stand-in of Flamenco's job-compiler API (author.Task/Command, path.join, frameChunker), its tasks are
run in order as a worker would run them, through ``blender -b BLEND -c smbs_bake ARGS`` (here the
command's function, with the .blend open in the bpy module): the shards of each frame, then their merge."""
import importlib
import json
import shutil
import subprocess

import pytest

from testkit import ROOT

bpy = pytest.importorskip("bpy")

from smbs_addon.io.exr import read_header  # noqa: E402

HARNESS = """
const fs = require("fs");
const tasks = [];
const author = {
  Task: (name, type) => ({name, type, commands: [], deps: [],
                          addCommand(c) { this.commands.push(c); }, addDependency(t) { this.deps.push(t.name); }}),
  Command: (name, parameters) => ({name, parameters}),
};
const path = {join: (...parts) => parts.join("/")};
function frameChunker(frames, size) {  // Flamenco's, for "A-B" and chunks of one
  const [a, b] = frames.split("-").map(Number);
  const out = [];
  for (let f = a; f <= (b === undefined ? a : b); f++) out.push(`${f}`);
  return out;
}
const job = {settings: JSON.parse(process.argv[2]), addTask(t) { tasks.push(t); }};
eval(fs.readFileSync(process.argv[1], "utf8") + "\\ncompileJob(job);");
console.log(JSON.stringify(tasks.map(t => ({name: t.name, type: t.type, deps: t.deps, commands: t.commands}))));
"""


def _compile(settings):
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    proc = subprocess.run([node, "-e", HARNESS, str(ROOT / "farm" / "flamenco" / "smbs_caustics.js"),
                           json.dumps(settings)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_the_flamenco_job_bakes_shards_and_merges_them(addon, tmp_path):
    from testkit.motion_scenes import small_moving_light

    blend = small_moving_light(tmp_path / "moving.blend", 25)
    out = tmp_path / "farm"
    settings = {"blender_cmd": "blender", "blender_args": "", "blendfile": str(blend), "frames": "3-4",
                "output_dir": str(out), "output_name": "caustics_####.exr", "shards": 2, "stop_rule": "spp",
                "stop_value": "4", "method": "reference", "seed": 1}
    tasks = _compile(settings)
    assert [t["name"] for t in tasks] == ["bake-3-shard-1", "bake-3-shard-2", "merge-3",
                                          "bake-4-shard-1", "bake-4-shard-2", "merge-4"]
    assert tasks[2]["deps"] == ["bake-3-shard-1", "bake-3-shard-2"] and tasks[0]["deps"] == []
    cli = importlib.import_module(addon.__name__ + ".operators.cli")
    (out / "shards").mkdir(parents=True)  # a worker's job folder; Flamenco's jobs make it so
    for t in tasks:  # in the order of their dependencies, as a worker runs them
        (cmd,) = t["commands"]
        p = cmd["parameters"]
        assert cmd["name"] == "blender-render" and p["argsBefore"] == ["-b"] and p["blendfile"] == str(blend)
        assert p["args"][:2] == ["-c", "smbs_bake"]
        bpy.ops.wm.open_mainfile(filepath=p["blendfile"], load_ui=False)  # blender -b BLEND
        assert cli.smbs_bake(p["args"][2:] + ["--quiet"]) == 0, t["name"]
    for f in (3, 4):
        meta = read_header(out / f"caustics_{f:04d}.exr")
        assert meta["frame"] == f and meta["samples"] == 4 and meta["merged"] == 2, meta
