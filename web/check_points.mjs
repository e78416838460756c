// Reads a LAS, LAZ or COPC file with decoders that are not skyfall's own and
// prints one JSON object, so that the tests can hold the writer to them.
// Usage: node check_points.mjs FILE
//
// Decoders: plain LAS records are read from the bytes; LAZ is decompressed
// with laz-perf's LASZip (the whole file, through its chunk table); COPC is
// walked with copc.js: every hierarchy page, then every node's chunk through
// laz-perf's ChunkDecoder, checking that each point lies in its node's cube.
//
// Prints: format ("las" | "laz" | "copc"), count (header), decoded (records
// decoded), scale, offset, header_mins/header_maxs, mins/maxs (of the decoded
// coordinates), crs_wkt (the LASF_Projection 2112 VLR), classes (points per
// class), records_sha256 (SHA-256 of the decoded records sorted bytewise, so
// that files holding the same records in another order agree) and, for COPC,
// nodes, node_points (their sum) and outside (points outside their node).
import crypto from "node:crypto";
import fs from "node:fs";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const { Copc, Key, Bounds } = require("copc");
const { createLazPerf } = require("laz-perf");

const path = process.argv[2];
const file = new Uint8Array(fs.readFileSync(path));
const dv = new DataView(file.buffer, file.byteOffset, file.byteLength);
const text = (at, n) => new TextDecoder().decode(file.subarray(at, at + n)).replace(/\0.*$/s, "");

// Header fields by their LAS 1.4 offsets.
const pointOffset = dv.getUint32(96, true);
const vlrCount = dv.getUint32(100, true);
const format = file[104] & 0x3f;
const compressed = (file[104] & 0x80) !== 0;
const recordLength = dv.getUint16(105, true);
const count = file[25] >= 4 ? Number(dv.getBigUint64(247, true)) : dv.getUint32(107, true);
const f64 = (at) => dv.getFloat64(at, true);
const scale = [0, 1, 2].map((a) => f64(131 + 8 * a));
const offset = [0, 1, 2].map((a) => f64(155 + 8 * a));
const headerMaxs = [0, 1, 2].map((a) => f64(179 + 16 * a));
const headerMins = [0, 1, 2].map((a) => f64(187 + 16 * a));

let crsWkt = "";
let isCopc = false;
for (let v = 0, at = dv.getUint16(94, true); v < vlrCount; ++v) {
  const user = text(at + 2, 16), record = dv.getUint16(at + 18, true), length = dv.getUint16(at + 20, true);
  if (user === "LASF_Projection" && record === 2112) crsWkt = text(at + 54, length);
  if (v === 0 && user === "copc" && record === 1) isCopc = true;
  at += 54 + length;
}

const records = [];  // each a Uint8Array of recordLength bytes
const result = { format: isCopc ? "copc" : compressed ? "laz" : "las" };

if (!compressed) {
  for (let i = 0; i < count; ++i) {
    records.push(file.slice(pointOffset + i * recordLength, pointOffset + (i + 1) * recordLength));
  }
} else if (!isCopc) {
  const L = await createLazPerf();
  const filePtr = L._malloc(file.length), pointPtr = L._malloc(recordLength);
  L.HEAPU8.set(file, filePtr);
  const reader = new L.LASZip();
  reader.open(filePtr, file.length);
  for (let i = 0; i < reader.getCount(); ++i) {
    reader.getPoint(pointPtr);
    records.push(L.HEAPU8.slice(pointPtr, pointPtr + recordLength));
  }
  reader.delete();
} else {
  const lazPerf = await createLazPerf();
  const copc = await Copc.create(path);
  const nodes = {};
  const pages = [copc.info.rootHierarchyPage];
  while (pages.length) {
    const page = await Copc.loadHierarchyPage(path, pages.pop());
    Object.assign(nodes, page.nodes);
    pages.push(...Object.values(page.pages));
  }
  let outside = 0, nodePoints = 0;
  for (const [key, node] of Object.entries(nodes)) {
    nodePoints += node.pointCount;
    if (node.pointCount === 0) continue;
    const bytes = await Copc.loadPointDataBuffer(path, copc.header, node, lazPerf);
    const cube = Bounds.stepTo(copc.info.cube, Key.create(key));
    for (let i = 0; i < node.pointCount; ++i) {
      const r = bytes.slice(i * recordLength, (i + 1) * recordLength);
      const rv = new DataView(r.buffer);
      const p = [0, 1, 2].map((a) => rv.getInt32(4 * a, true) * scale[a] + offset[a]);
      if (p.some((x, a) => x < cube[a] - 1e-9 || x > cube[a + 3] + 1e-9)) ++outside;
      records.push(r);
    }
  }
  Object.assign(result, { nodes: Object.keys(nodes).length, node_points: nodePoints, outside });
}

const mins = [Infinity, Infinity, Infinity], maxs = [-Infinity, -Infinity, -Infinity];
const classes = {};
const classByte = format >= 6 ? 16 : 15;
for (const r of records) {
  const rv = new DataView(r.buffer, r.byteOffset, r.byteLength);
  for (let a = 0; a < 3; ++a) {
    const x = rv.getInt32(4 * a, true) * scale[a] + offset[a];
    mins[a] = Math.min(mins[a], x);
    maxs[a] = Math.max(maxs[a], x);
  }
  const c = format >= 6 ? r[classByte] : r[classByte] & 0x1f;
  classes[c] = (classes[c] ?? 0) + 1;
}
const sorted = records.map((r) => Buffer.from(r)).sort(Buffer.compare);
const sha = crypto.createHash("sha256");
for (const r of sorted) sha.update(r);

console.log(JSON.stringify({
  ...result, point_format: format, count, decoded: records.length, scale, offset,
  header_mins: headerMins, header_maxs: headerMaxs, mins, maxs, crs_wkt: crsWkt, classes,
  records_sha256: sha.digest("hex"),
}));
