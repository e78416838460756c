// Opens a page in a real browser (Debian's Chromium, headless, WebGL through
// SwiftShader) and reports what a user would meet. Usage:
//   node check_page.mjs URL SCREENSHOT.png [--viewer]
// Requests that leave the machine are refused and listed, which proves the
// page works offline. With --viewer, waits (up to 4 min) for the skyfall
// viewer's window.skyfallStatus to say every visible tile loaded or an error
// happened. Prints one JSON object: {url, status, external, errors, images}.
import { openOfflinePage } from "./offline_page.mjs";

const [url, screenshot, mode] = process.argv.slice(2);
const { browser, page, external, errors } = await openOfflinePage();
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
