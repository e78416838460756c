// Checks skyfall's glTF splat content with tools that are not skyfall's own:
// the Khronos glTF validator and the spz-loader decoder (the one CesiumJS
// uses). Usage: node check_splats.mjs FILE.glb...
// Prints one JSON object per file: {file, errors, ignored, numPoints,
// shDegree, version, fractionalBits, positions, alphas, scales, rotations,
// colors, sh} (decoded values as the loader gives
// them, coordinates as stored).
import fs from "node:fs";
import zlib from "node:zlib";
import validator from "gltf-validator";

// spz-loader's bundle embeds its WebAssembly but, under Node, tries to load
// Node modules through a stub; told it runs in a renderer, it takes the
// browser path, which needs nothing from the file system.
process.type = "renderer";
const { loadSpz } = await import("@spz-loader/core");

// The validator does not know KHR_gaussian_splatting yet and reports its
// attribute names as invalid; that one message is expected, nothing else.
const UNKNOWN_SEMANTIC = "MESH_PRIMITIVE_INVALID_ATTRIBUTE";

function spzBytes(glb) {
  const view = new DataView(glb.buffer, glb.byteOffset, glb.byteLength);
  const jsonLength = view.getUint32(12, true);
  const gltf = JSON.parse(new TextDecoder().decode(glb.subarray(20, 20 + jsonLength)));
  const binStart = 20 + jsonLength + 8;
  const bv = gltf.bufferViews[0];
  return glb.subarray(binStart + (bv.byteOffset ?? 0), binStart + (bv.byteOffset ?? 0) + bv.byteLength);
}

for (const file of process.argv.slice(2)) {
  const glb = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(glb, { maxIssues: 1000 });
  const errors = [];
  let ignored = 0;
  for (const m of report.issues.messages) {
    if (m.severity !== 0) continue;
    if (m.code === UNKNOWN_SEMANTIC && /KHR_gaussian_splatting:/.test(m.pointer + m.message)) {
      ++ignored;
      continue;
    }
    errors.push({ code: m.code, message: m.message, pointer: m.pointer });
  }
  const spz = spzBytes(glb);
  const cloud = await loadSpz(spz, { unpackOptions: { coordinateSystem: "UNSPECIFIED" } });
  const header = zlib.gunzipSync(spz).subarray(0, 16);  // magic, version, count, SH degree, fractional bits, ...
  console.log(JSON.stringify({
    file,
    errors,
    ignored,
    numPoints: cloud.numPoints,
    shDegree: cloud.shDegree,
    version: new DataView(header.buffer, header.byteOffset).getUint32(4, true),
    fractionalBits: header[13],
    positions: Array.from(cloud.positions),
    alphas: Array.from(cloud.alphas),
    scales: Array.from(cloud.scales),
    rotations: Array.from(cloud.rotations),
    colors: Array.from(cloud.colors),
    sh: Array.from(cloud.sh),
  }));
}
