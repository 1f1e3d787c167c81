// Compiles a Flamenco job type the way the Manager does, with no Manager: the job compiler's
// documented globals (author.Job, author.Task, author.Command, frameChunker, shellSplit, print),
// written here from Flamenco's documentation and its own frameChunker test cases.
//   node flamenco_harness.js JOB_TYPE.js SETTINGS.json  ->  {"tasks": [...]} or {"error": "..."}
"use strict";
const fs = require("fs");
const vm = require("vm");

// Flamenco's frameChunker: frames of "1-10,20..25,40" in order, without repeats, cut into runs of
// at most SIZE, each written back as "A-B", "N" or "A,B" (two frames), runs joined by commas.
function frameChunker(frames, size) {
  const numbers = new Set();
  for (const part of `${frames}`.replaceAll("..", "-").split(",")) {
    const ends = part.split("-").map((word) => word.trim());
    if (ends.length > 2 || ends.some((word) => !/^\d+$/.test(word))) {
      throw `invalid range "${frames}": ${part}`;
    }
    for (let frame = Number(ends[0]); frame <= Number(ends[ends.length - 1]); frame++) {
      numbers.add(frame);
    }
  }
  if (numbers.size === 0 || !(size >= 1)) {
    throw `invalid range "${frames}" or chunk size ${size}`;
  }
  const sorted = [...numbers].sort((a, b) => a - b);
  const chunks = [];
  for (let i = 0; i < sorted.length; i += size) {
    chunks.push(mergeFrames(sorted.slice(i, i + size)));
  }
  return chunks;
}

function mergeFrames(frames) {
  const runs = [];
  let start = frames[0];
  for (let i = 1; i <= frames.length; i++) {
    if (i === frames.length || frames[i] !== frames[i - 1] + 1) {
      const end = frames[i - 1];
      runs.push(start === end ? `${start}` : start + 1 === end ? `${start},${end}` : `${start}-${end}`);
      start = frames[i];
    }
  }
  return runs.join(",");
}

function shellSplit(text) {
  const words = [];
  const pattern = /"([^"]*)"|'([^']*)'|(\S+)/g;
  let match;
  while ((match = pattern.exec(text)) !== null) {
    words.push(match[1] ?? match[2] ?? match[3]);
  }
  return words;
}

const author = {
  Job(name, settings) {
    const job = { name, settings, created: new Date(0), tasks: [] };
    job.addTask = (task) => job.tasks.push(task);
    return job;
  },
  Task(name, type) {
    const task = { name, type, commands: [], dependencies: [] };
    task.addCommand = (command) => task.commands.push(command);
    task.addDependency = (other) => task.dependencies.push(other.name);
    return task;
  },
  Command(type, parameters) {
    return { type, parameters };
  },
};

function selfCheck() {
  // Flamenco's own cases (internal/manager/job_compilers/js_globals_test.go).
  const cases = [[["1-10,20-25,40", 4], ["1-4", "5-8", "9,10,20,21", "22-25", "40"]],
                 [["1..10,20..25,40,3..8", 4], ["1-4", "5-8", "9,10,20,21", "22-25", "40"]],
                 [["47", 4], ["47"]], [["1-3", 3], ["1-3"]]];
  for (const [args, expected] of cases) {
    const got = frameChunker(...args);
    if (JSON.stringify(got) !== JSON.stringify(expected)) {
      throw `harness frameChunker(${args}) = ${JSON.stringify(got)}, Flamenco gives ${JSON.stringify(expected)}`;
    }
  }
}

function main() {
  selfCheck();
  const [jobTypePath, settingsPath] = process.argv.slice(2);
  const context = vm.createContext({ author, frameChunker, shellSplit, print: () => {}, console });
  const exported = vm.runInContext(`${fs.readFileSync(jobTypePath, "utf8")}\n;({ JOB_TYPE, compileJob })`,
                                   context, { filename: jobTypePath });
  const given = JSON.parse(fs.readFileSync(settingsPath, "utf8"));
  const settings = {};
  for (const setting of exported.JOB_TYPE.settings) {
    if (setting.default !== undefined) settings[setting.key] = setting.default;
  }
  Object.assign(settings, given);
  const missing = exported.JOB_TYPE.settings.filter((s) => s.required && settings[s.key] === undefined);
  if (missing.length) {
    throw `required settings missing: ${missing.map((s) => s.key).join(", ")}`;
  }
  const job = author.Job("test job", settings);
  try {
    exported.compileJob(job);
  } catch (error) {
    process.stdout.write(JSON.stringify({ error: `${error}` }));
    return;
  }
  process.stdout.write(JSON.stringify({ label: exported.JOB_TYPE.label, tasks: job.tasks }));
}

main();
