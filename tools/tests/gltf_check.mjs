// The export check (tools/tests/export.rs runs it with node):
//   node gltf_check.mjs VALIDATOR_DIR RUN.glb FRAMES_DIR
// validates RUN.glb with the Khronos glTF-Validator, then reads it back
// with the plain GLB layout (header, JSON chunk, BIN chunk) and compares
// what a viewer would show at each key time with what `cloth run` wrote:
// the cloth (first frame + that frame's morph target, as the one-hot
// weights select it) against the OBJ frames, and the solids' keyed
// translations and rotations against solids.json. Prints one JSON line.
import { readFileSync, readdirSync } from "fs";
import { createRequire } from "module";

const [validatorDir, glbPath, framesDir] = process.argv.slice(2);
const validator = createRequire(import.meta.url)(validatorDir);
const bytes = new Uint8Array(readFileSync(glbPath));
const report = await validator.validateBytes(bytes);

const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
const jsonLength = view.getUint32(12, true);
const doc = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
const binStart = 20 + jsonLength + 8;
function floats(accessor) {
  const a = doc.accessors[accessor], v = doc.bufferViews[a.bufferView];
  const width = { SCALAR: 1, VEC3: 3, VEC4: 4 }[a.type];
  return new Float32Array(bytes.buffer.slice(bytes.byteOffset + binStart + v.byteOffset, bytes.byteOffset + binStart + v.byteOffset + a.count * width * 4));
}

const objs = readdirSync(framesDir).filter((n) => /^frame_\d+\.obj$/.test(n)).sort();
const objFrames = objs.map((n) => readFileSync(`${framesDir}/${n}`, "utf8").split("\n")
  .filter((l) => l.startsWith("v ")).flatMap((l) => l.trim().split(/\s+/).slice(1).map(Number)));

const cloth = doc.meshes[0].primitives[0];
const base = floats(cloth.attributes.POSITION);
const animation = doc.animations[0];
const weightsSampler = animation.samplers[animation.channels.find((c) => c.target.path === "weights").sampler];
const times = floats(weightsSampler.input), weights = floats(weightsSampler.output);
const targets = cloth.targets.length;
let clothError = 0, weightError = 0;
for (let k = 0; k < times.length; k++) {
  const w = weights.subarray(k * targets, (k + 1) * targets);
  const shown = Float32Array.from(base);
  w.forEach((wt, t) => {
    weightError = Math.max(weightError, Math.abs(wt - (t === k - 1 ? 1 : 0)));
    if (wt !== 0) floats(cloth.targets[t].POSITION).forEach((d, i) => { shown[i] += wt * d; });
  });
  shown.forEach((c, i) => { clothError = Math.max(clothError, Math.abs(c - objFrames[k][i])); });
}

const solids = JSON.parse(readFileSync(`${framesDir}/solids.json`, "utf8"));
const byStep = new Map(solids.frames.map((f) => [f.step, f.poses]));
const steps = objs.map((n) => +n.slice(6, -4));
let poseError = 0, solidNodes = 0;
for (const channel of animation.channels.filter((c) => c.target.path !== "weights")) {
  const node = doc.nodes[channel.target.node], s = +node.name.split(" ")[1];
  const values = floats(animation.samplers[channel.sampler].output);
  steps.forEach((step, k) => {
    const p = byStep.get(step)[s];
    const expected = channel.target.path === "translation" ? [p[0], p[1], p[2]] : [p[4], p[5], p[6], p[3]];
    expected.forEach((e, a) => { poseError = Math.max(poseError, Math.abs(values[k * expected.length + a] - e)); });
  });
  solidNodes += channel.target.path === "translation" ? 1 : 0;
}
const root = doc.nodes[doc.scenes[0].nodes[0]];
console.log(JSON.stringify({
  errors: report.issues.numErrors, warnings: report.issues.numWarnings,
  messages: report.issues.messages.slice(0, 5).map((m) => `${m.code}: ${m.message}`),
  frames: times.length, objFrames: objFrames.length, targets, solidNodes,
  clothError, weightError, poseError, rootRotation: root.rotation,
  lastTime: times[times.length - 1],
}));
