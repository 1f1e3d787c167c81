// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "Stochastic SSR Render": a shot rendered with the Stochastic SSR add-on, one
// task per chunk of frames. Drop this file into the Flamenco Manager's `scripts/` folder and
// restart the Manager (README, "On a render farm").
//
// Each task runs the add-on's command line in Blender on the workers:
//   blender -b SHOT.blend --python-expr "<import the add-on; run its CLI>" --
//       render --frames A-B --warmup K --out FOLDER --set preset=P [more options]
// `--warmup K` renders the K frames before A without writing them, so frame A carries the
// temporal history an uninterrupted run would give it; they print no "Saved:" lines, which the
// worker takes for outputs. Every chunk writes into the same output folder: the add-on keeps
// one record per chunk there, so chunks rendered at the same time never lose each other's frames.

const JOB_TYPE = {
  label: "Stochastic SSR Render",
  settings: [
    { key: "frames", type: "string", required: true,
      eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      evalInfo: { showLinkButton: true, description: "Scene frame range" },
      description: "Frames to render: one range A-B, or one frame N" },
    { key: "chunk_size", type: "int32", default: 30, propargs: { min: 1 }, visible: "submission",
      description: "Frames each task renders" },
    { key: "warmup", type: "int32", default: 8, propargs: { min: 0, max: 64 }, visible: "submission",
      description: "Frames each task renders before its first, unwritten, to warm the temporal history "
        + "(each task costs this many extra frames)" },
    { key: "output_folder", type: "string", subtype: "dir_path", required: true, visible: "submission",
      description: "Folder the frames and report.json are written to, shared by every task" },
    { key: "preset", type: "string", default: "balanced", choices: ["draft", "balanced", "high"],
      visible: "submission", description: "Quality preset of the reflections" },
    { key: "render_options", type: "string", default: "", visible: "submission",
      description: "More options of the add-on's render command, e.g. '--resolution 1920x1080 --set thickness=0.1'" },
    { key: "addon_folder", type: "string", subtype: "dir_path", required: true, visible: "submission",
      description: "Folder holding the add-on's ssr_addon package on the workers (where the extension is installed)" },
    { key: "blendfile", type: "string", required: true, visible: "web",
      description: "Path of the blend file to render" },
  ],
};

// A plain range "A-B" (or "A..B") or one frame "N": the chunks must each be a run of
// consecutive frames of one shot, since each warms its history on the frames before it.
const SINGLE_RANGE = /^\s*(\d+)\s*(?:(?:-|\.\.)\s*(\d+)\s*)?$/;

function compileJob(job) {
  const settings = job.settings;
  const match = SINGLE_RANGE.exec(`${settings.frames}`);
  if (!match) {
    throw `frames "${settings.frames}": give one range A-B or one frame N (a shot's temporal history runs through its frames)`;
  }
  const first = Number(match[1]);
  const last = match[2] === undefined ? first : Number(match[2]);
  if (last < first) {
    throw `frames "${settings.frames}": the range is reversed`;
  }
  if (!(settings.chunk_size >= 1)) {
    throw `chunk_size ${settings.chunk_size}: give at least 1 frame`;
  }
  if (!(settings.warmup >= 0)) {
    throw `warmup ${settings.warmup}: give 0 or more frames`;
  }
  for (const chunk of frameChunker(`${first}-${last}`, settings.chunk_size)) {
    job.addTask(renderTask(settings, chunkRange(chunk)));
  }
}

// frameChunker writes a chunk as "A-B", "N" or, for two frames, "A,B": the add-on takes "A-B".
function chunkRange(chunk) {
  const frames = chunk.split(/[,-]/).map(Number);
  return `${frames[0]}-${frames[frames.length - 1]}`;
}

function renderTask(settings, range) {
  const importAddon = `import sys; sys.path.insert(0, ${JSON.stringify(settings.addon_folder)}); `
    + "import ssr_addon.batch.cli as cli; cli.main()";
  const task = author.Task(`ssr-render-${range}`, "blender");
  task.addCommand(author.Command("blender-render", {
    exe: "{blender}",
    exeArgs: "{blenderArgs}",
    argsBefore: [],
    blendfile: settings.blendfile,
    args: [
      "--python-expr", importAddon, "--",
      "render", "--frames", range, "--warmup", `${settings.warmup}`, "--out", settings.output_folder,
      "--set", `preset=${settings.preset}`,
      ...(settings.render_options ? shellSplit(settings.render_options) : []),
    ],
  }));
  return task;
}
