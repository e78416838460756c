// Reads a LAS file with loaders.gl, a reader that is not skyfall's own.
// Usage: node check_las.mjs FILE.las
// Prints one JSON object: {count, mins, maxs, scale, offset} from the
// loader's header and {classes} (points per classification) from the records
// it decoded.
import fs from "node:fs";
import { parse } from "@loaders.gl/core";
import { LAZRsLoader } from "@loaders.gl/las";

// LAZRsLoader (laz-rs in WebAssembly) is the loader that knows LAS 1.4; the
// default LASLoader (laz-perf) does not. It fetches its .wasm beside itself,
// and Node's fetch does not do file: URLs, so those are served from disk here.
const nodeFetch = globalThis.fetch;
globalThis.fetch = async (url, ...rest) =>
  String(url).startsWith("file:")
    ? new Response(fs.readFileSync(new URL(url)), { headers: { "Content-Type": "application/wasm" } })
    : nodeFetch(url, ...rest);

const bytes = fs.readFileSync(process.argv[2]);
const mesh = await parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), LAZRsLoader, {
  worker: false,
  las: { fp64: true },
});
const header = mesh.loaderData;
const classes = {};
for (const c of mesh.attributes.classification.value) classes[c] = (classes[c] ?? 0) + 1;
console.log(JSON.stringify({
  count: header.pointsCount,
  mins: header.mins,
  maxs: header.maxs,
  scale: header.scale,
  offset: header.offset,
  classes,
}));
