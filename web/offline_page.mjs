// A page in a real browser (Debian's Chromium, headless, WebGL through
// SwiftShader) that may reach this machine only: every request off it is
// refused and listed in `external`, which proves a page works offline;
// console errors and uncaught exceptions are listed in `errors`.
import { chromium } from "playwright-core";

export async function openOfflinePage() {
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
  return { browser, page, external, errors };
}
