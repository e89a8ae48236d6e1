// SMBS Caustics as a Flamenco 3 job type: the job of farm/openjd/smbs_caustics.yaml (docs/farm.md).
//
// Put this file in the `scripts` folder beside flamenco-manager. Each worker runs Blender with the
// extension installed and enabled: per frame x shard a task
//     {blender} {blenderArgs} -b BLEND -c smbs_bake --frame F --shard K/N --STOP VALUE --method M --seed S --out DIR/shards/sK_NAME
// and per frame, after all of that frame's shards, a task
//     {blender} {blenderArgs} -b BLEND -c smbs_bake merge DIR/NAME --frame F DIR/shards/s*_NAME
// (merge fills the # run with F and matches the * itself, so no shell is needed). The exit codes are the
// command line's (docs/farm.md): 0 done, 1 scene, 2 arguments, 3 input/output, 128 + signal.
// Written against Flamenco 3's job-type API (author.Task, author.Command("blender-render"), frameChunker);
// not run in this project's CI, which runs the OpenJD template instead.

const JOB_TYPE = {
    label: "SMBS Caustics",
    description: "Bake the caustic layer of each frame in shards, then merge each frame's shards",
    settings: [
        { key: "blender_cmd", type: "string", default: "{blender}", visible: "hidden" },
        { key: "blender_args", type: "string", default: "{blenderArgs}", visible: "hidden" },
        { key: "blendfile", type: "string", subtype: "file_path", required: true,
          description: "The .blend to bake (its scene at each frame)" },
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          description: "The frames, e.g. 1-250 or 1-250,300" },
        { key: "output_dir", type: "string", subtype: "dir_path", required: true,
          description: "Where the frames go (the shards in its folder shards/)" },
        { key: "output_name", type: "string", default: "caustics_####.exr",
          description: "A frame's file; the run of # is the frame (Blender's convention)" },
        { key: "shards", type: "int32", default: 4, description: "Independent shares of each frame's samples" },
        { key: "stop_rule", type: "string", default: "spp", choices: ["spp", "time", "noise"],
          description: "spp: samples per pixel of the frame; time: seconds per shard; noise: the frame's error bar" },
        { key: "stop_value", type: "string", default: "64" },
        { key: "method", type: "string", default: "auto", choices: ["auto", "reference", "mnee", "sms", "smbs"] },
        { key: "seed", type: "int32", default: 0 },
    ],
};

function compileJob(job) {
    const s = job.settings;
    const shardsDir = path.join(s.output_dir, "shards");
    for (const chunk of frameChunker(s.frames, 1)) {
        const frame = chunk.split("-")[0];  // chunks of one frame: "12"
        const bakes = [];
        for (let k = 1; k <= s.shards; k++) {
            const task = author.Task(`bake-${frame}-shard-${k}`, "blender");
            task.addCommand(smbsBake(s, [
                "--frame", frame, "--shard", `${k}/${s.shards}`, `--${s.stop_rule}`, s.stop_value,
                "--method", s.method, "--seed", `${s.seed}`,
                "--out", path.join(shardsDir, `s${k}_${s.output_name}`),
            ]));
            job.addTask(task);
            bakes.push(task);
        }
        const merge = author.Task(`merge-${frame}`, "blender");
        merge.addCommand(smbsBake(s, [
            "merge", path.join(s.output_dir, s.output_name), "--frame", frame,
            path.join(shardsDir, `s*_${s.output_name}`),
        ]));
        for (const t of bakes) {
            merge.addDependency(t);
        }
        job.addTask(merge);
    }
}

// blender -b BLEND -c smbs_bake ARGS: Blender opens the file, then runs the extension's command.
function smbsBake(s, args) {
    return author.Command("blender-render", {
        exe: s.blender_cmd,
        exeArgs: s.blender_args,
        argsBefore: ["-b"],
        blendfile: s.blendfile,
        args: ["-c", "smbs_bake"].concat(args),
    });
}
