// The skyfall viewer on a city, in a real browser (Debian's Chromium,
// headless, WebGL through SwiftShader), as a user meets it: the whole city
// first, then the camera down to a street. Usage:
//   node check_city_view.mjs VIEWER_URL OUT_DIR [--street-height-m 150] [--min-visible-fraction 0.02]
// VIEWER_URL is the page `skyfall view` serves (http://127.0.0.1:PORT/view/index.html).
// Per view it reports the 3D Tiles requests (tileset JSON and GLB contents),
// their bytes, the depth in the tree of every content fetched, and the
// seconds until the viewer said every visible tile had loaded (the first
// complete frame), and the share of the view's pixels the tileset changes
// (the same frame rendered without it: a city drawn behind the ground, or
// not at all, changes none); it writes whole_city.png and street.png into OUT_DIR.
// A streaming tileset loads the whole city without fetching every leaf and
// fetches deeper contents for the street. Requests off the machine are
// refused and listed. Prints one JSON object; exits 1 when a view failed.
import { openOfflinePage } from "./offline_page.mjs";
import fs from "node:fs";
import path from "node:path";

const args = process.argv.slice(2);
const [url, outDir] = args;
const streetAt = args.indexOf("--street-height-m");
const streetHeightM = streetAt >= 0 ? Number(args[streetAt + 1]) : 150;
// The city must show: at least this share of each view's pixels is the
// tileset's (the 1 km city fills about a tenth of the whole-city view).
const visibleAt = args.indexOf("--min-visible-fraction");
const minVisibleFraction = visibleAt >= 0 ? Number(args[visibleAt + 1]) : 0.02;
if (!url || !outDir || !(streetHeightM > 0) || !(minVisibleFraction >= 0)) {
  console.error("usage: node check_city_view.mjs VIEWER_URL OUT_DIR [--street-height-m M] [--min-visible-fraction F]");
  process.exit(2);
}

// Depth of every content URI in the tileset (root = 0), and how many there are per depth.
async function tilesetDepths(tilesetUrl) {
  const doc = await (await fetch(tilesetUrl)).json();
  const depthOf = new Map();
  const perDepth = [];
  const walk = (tile, depth) => {
    if (tile.content && tile.content.uri) {
      depthOf.set(new URL(tile.content.uri, tilesetUrl).pathname, depth);
      perDepth[depth] = (perDepth[depth] ?? 0) + 1;
    }
    for (const child of tile.children ?? []) walk(child, depth + 1);
  };
  walk(doc.root, 0);
  return { depthOf, perDepth };
}

const { browser, page, external, errors } = await openOfflinePage();
const fetched = [];  // {path, bytes} of every 3D Tiles request, in order
page.on("requestfinished", async (request) => {
  const u = new URL(request.url());
  if (!u.pathname.includes("/3dtiles/")) return;
  const sizes = await request.sizes();
  fetched.push({ path: u.pathname, bytes: sizes.responseBodySize });
});

const waitLoaded = async () => {
  // Cesium says "all tiles loaded" when loading ends; a view that needs no
  // tile the last one did not load (a small city whose first view fetched
  // every content) starts no loading and never says it. So a view moved to
  // (skyfallStatus.movedAtFrame) also counts as loaded once a few frames
  // have rendered it and the tileset reports every tile it needs loaded.
  await page.waitForFunction(() => {
    const s = window.skyfallStatus, v = window.skyfallView;
    if (!s) return false;
    if (s.loaded || s.errors.length > 0) return true;
    return s.movedAtFrame !== undefined && v !== undefined &&
      v.viewer.scene.frameState.frameNumber > s.movedAtFrame + 3 && v.tileset.tilesLoaded;
  }, null, { timeout: 240000 });
  // "All tiles loaded" comes before the splats can be drawn: the tileset's
  // splat primitive still builds its textures and sorts in a worker (seconds
  // under SwiftShader on a busy machine), and commits them together. A frame
  // that settled before the first commit showed no splat at all: the whole
  // city's visible share read 0 in CI for a tileset that draws 7% of the
  // view. `_hasGaussianSplatTexture` is Cesium's own "a sorted snapshot is
  // committed" flag. Later snapshots (finer tiles as they load) replace a
  // drawn one, and a frame taken before they commit shows the coarser tiles:
  // so the wait is also for the primitive to be idle, with no snapshot to
  // rebuild, none pending and no sort running. These are private fields,
  // hence the timeout.
  await page.waitForFunction(() => {
    const splats = window.skyfallView && window.skyfallView.tileset.gaussianSplatPrimitive;
    return splats !== undefined && splats._hasGaussianSplatTexture === true && !splats._needsSnapshotRebuild &&
      !splats._dirty && splats._pendingSnapshot === undefined && splats._pendingSortPromise === undefined;
  }, null, { timeout: 60000 }).catch(() => {});
  await page.waitForTimeout(1000);  // let the last responses be counted
};

// Share of the view's pixels the tileset changes: the view rendered with and
// without it (a city hidden behind the ground, or not drawn, changes none).
// Share of pixels that differ between two PNG screenshots (base64), decoded
// by the page's own canvas.
const changedFraction = (a, b) => page.evaluate(async ([a, b]) => {
  const pixels = async (png) => {
    const image = new Image();
    image.src = "data:image/png;base64," + png;
    await image.decode();
    const c = document.createElement("canvas");
    c.width = image.width;
    c.height = image.height;
    const g = c.getContext("2d");
    g.drawImage(image, 0, 0);
    return g.getImageData(0, 0, c.width, c.height).data;
  };
  const [p, q] = [await pixels(a), await pixels(b)];
  let changed = 0;
  for (let i = 0; i < p.length; i += 4) {
    const d = Math.abs(p[i] - q[i]) + Math.abs(p[i + 1] - q[i + 1]) + Math.abs(p[i + 2] - q[i + 2]);
    if (d > 48) ++changed;  // more than 16 grey levels a channel on average: not noise
  }
  return changed / (p.length / 4);
}, [a, b]);

// Screenshots until two in a row agree (the splats are drawn some frames
// after Cesium says the tiles loaded): the settled frame and when it was
// first seen [s since `t0`]. A screenshot takes 1-3 s under SwiftShader,
// which is the resolution of the time.
const settle = async (t0) => {
  const shot = async () => ({ png: (await page.screenshot()).toString("base64"), at: (Date.now() - t0) / 1000 });
  let last = await shot();
  for (let k = 0; k < 60; ++k) {
    await page.waitForTimeout(500);
    const next = await shot();
    if (await changedFraction(last.png, next.png) < 0.001) return last;
    last = next;
  }
  return last;  // never settled: the figures say so through their time
};

// Share of the settled view's pixels the tileset changes: the view settled
// again without it (a city hidden behind the ground, or not drawn, changes none).
const tilesetVisibleFraction = async (shown) => {
  await page.evaluate(() => { window.skyfallView.tileset.show = false; });
  const hidden = await settle(Date.now());
  await page.evaluate(() => { window.skyfallView.tileset.show = true; });
  await settle(Date.now());
  return changedFraction(shown.png, hidden.png);
};

// The requests since `from`, summed, with the depth of each content.
const summarize = (from, depthOf) => {
  const mine = fetched.slice(from);
  const contents = mine.filter((f) => f.path.endsWith(".glb"));
  const byDepth = [];
  for (const c of contents) {
    const d = depthOf.get(c.path) ?? -1;
    byDepth[d] = (byDepth[d] ?? 0) + 1;
  }
  return { requests: mine.length, contents: contents.length, bytes: mine.reduce((s, f) => s + f.bytes, 0),
           contents_by_depth: Array.from(byDepth, (v) => v ?? 0) };
};

const start = Date.now();
await page.goto(url, { waitUntil: "load" });
await waitLoaded();
const wholeLoaded = (Date.now() - start) / 1000;
const wholeFrame = await settle(start);
const tilesetUrl = await page.evaluate(() => new URL(window.skyfallView.tileset.resource.url, location.href).href);
const { depthOf, perDepth } = await tilesetDepths(tilesetUrl);
const whole = { seconds_to_tiles_loaded: wholeLoaded, seconds_to_complete_frame: wholeFrame.at,
                ...summarize(0, depthOf), tileset_visible_fraction: await tilesetVisibleFraction(wholeFrame),
                all_tiles_loaded: await page.evaluate(() => window.skyfallView.tileset.tilesLoaded),
                status: await page.evaluate(() => window.skyfallStatus) };
fs.writeFileSync(path.join(outDir, "whole_city.png"), Buffer.from(wholeFrame.png, "base64"));

// Down to a street: the camera streetHeightM above the city's centre,
// looking 45 degrees down.
const mark = fetched.length;
const streetStart = Date.now();
await page.evaluate((h) => {
  const { viewer, tileset } = window.skyfallView;
  window.skyfallStatus.loaded = false;
  window.skyfallStatus.movedAtFrame = viewer.scene.frameState.frameNumber;
  const centre = Cesium.Cartographic.fromCartesian(tileset.boundingSphere.center);
  const ground = typeof config !== "undefined" ? config.ground_height_m : centre.height;
  // 45 degrees down: the point looked at lies h north of the camera.
  viewer.camera.setView({
    destination: Cesium.Cartesian3.fromRadians(centre.longitude, centre.latitude - h / 6371000, ground + h),
    orientation: { heading: 0, pitch: Cesium.Math.toRadians(-45), roll: 0 },
  });
}, streetHeightM);
await waitLoaded();
const streetLoaded = (Date.now() - streetStart) / 1000;
const streetFrame = await settle(streetStart);
const street = { seconds_to_tiles_loaded: streetLoaded, seconds_to_complete_frame: streetFrame.at,
                 ...summarize(mark, depthOf), tileset_visible_fraction: await tilesetVisibleFraction(streetFrame),
                 all_tiles_loaded: await page.evaluate(() => window.skyfallView.tileset.tilesLoaded),
                 status: await page.evaluate(() => window.skyfallStatus) };
fs.writeFileSync(path.join(outDir, "street.png"), Buffer.from(streetFrame.png, "base64"));

const deepest = (byDepth) => byDepth.reduce((d, v, k) => (v > 0 ? k : d), -1);
const leaves = perDepth.length - 1;
const report = {
  url, street_height_m: streetHeightM, min_visible_fraction: minVisibleFraction, contents_per_depth: Array.from(perDepth, (v) => v ?? 0),
  whole_city: whole, street,
  // Streams: the whole city shows without fetching every leaf, and the
  // street fetches contents deeper than the whole city did.
  whole_city_leaves_fetched: whole.contents_by_depth[leaves] ?? 0,
  streams: (whole.contents_by_depth[leaves] ?? 0) < perDepth[leaves] &&
           deepest(street.contents_by_depth) > deepest(whole.contents_by_depth),
  external, errors,
};
console.log(JSON.stringify(report));
await browser.close();
const failed = errors.length || external.length || whole.status.errors.length || street.status.errors.length ||
               whole.tileset_visible_fraction < minVisibleFraction || street.tileset_visible_fraction < minVisibleFraction;
process.exit(failed ? 1 : 0);
