// Opens a page in a real browser (Debian's Chromium, headless, WebGL through
// SwiftShader) and reports what a user would meet. Usage:
//   node check_page.mjs URL SCREENSHOT.png [--viewer]
// Requests that leave the machine are refused and listed, which proves the
// page works offline. With --viewer, waits (up to 4 min) for the skyfall
// viewer's window.skyfallStatus to say every visible tile loaded or an error
// happened. Prints one JSON object: {url, status, external, errors, images}.
import { chromium } from "playwright-core";

const [url, screenshot, mode] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
  args: ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--no-sandbox"],
});
const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
const external = [];
const errors = [];
const local = (u) => ["file:", "data:", "blob:"].includes(u.protocol) || ["127.0.0.1", "localhost"].includes(u.hostname);
await page.route(() => true, (route) => {
  if (local(new URL(route.request().url()))) return route.continue();
  external.push(route.request().url());
  return route.abort();
});
page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
page.on("pageerror", (e) => errors.push(String(e)));
await page.goto(url, { waitUntil: "load" });
let status = null;
if (mode === "--viewer") {
  await page.waitForFunction(() => window.skyfallStatus && (window.skyfallStatus.loaded ||
    window.skyfallStatus.errors.length > 0), null, { timeout: 240000 });
  await page.waitForTimeout(2000);  // a few more frames with everything loaded
  status = await page.evaluate(() => window.skyfallStatus);
}
const images = await page.evaluate(() => Array.from(document.images).map((i) => ({ alt: i.alt, width: i.naturalWidth })));
await page.screenshot({ path: screenshot });
console.log(JSON.stringify({ url, status, external, errors, images }));
await browser.close();
