// Drives Debian's chromium (headless, through playwright-core) to the viewer page and waits until
// every panel named in the criteria shows data, or the deadline passes. For
// test_live_view_browser.py:
//   node drive.js '<json>'   {playwright, chromium, url, deadline_s, out_dir, panels: {id: criterion}}
// criterion: {"text": ["any", "of these"]}  the panel's text contains one of them, or
//            {"colours": N, "warm": M}      its pixels (an element screenshot) have at least N
//                                           colours (quantized to 4 bits per channel) and at least
//                                           M pixels of a saturated colour that is not blue (the
//                                           3D view's empty scene: a light background, a blue grid).
// Prints one JSON line per poll ({"t", "panels": {id: {ok, t (s when it first showed data), text,
// colours}}}) and a last one with "done": true; saves page.png and one PNG per panel under
// out_dir. Times are from the start of the browser.
"use strict";

const fs = require("fs");
const path = require("path");

const args = JSON.parse(process.argv[2]);
const { chromium } = require(args.playwright);

function panelSelector(id) {
  return `[data-testid="panel-mouseenter-container ${id}"]`;
}

// Colours of a PNG, decoded in the page (node has no PNG decoder of its own here).
async function colours(page, png) {
  return await page.evaluate(async (b64) => {
    const blob = await (await fetch(`data:image/png;base64,${b64}`)).blob();
    const bitmap = await createImageBitmap(blob);
    const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
    const ctx = canvas.getContext("2d");
    ctx.drawImage(bitmap, 0, 0);
    const data = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    const seen = new Set();
    let warm = 0;
    for (let i = 0; i < data.length; i += 4) {
      const [r, g, b] = [data[i], data[i + 1], data[i + 2]];
      seen.add(((r >> 4) << 8) | ((g >> 4) << 4) | (b >> 4));
      const hi = Math.max(r, g, b);
      const lo = Math.min(r, g, b);
      // saturated and not blue (hue 180-260 deg: the 3D view's grid and its blends)
      if (hi - lo > 60 && !(b === hi && Math.min(r, g) < b - 30 && r <= g + 40)) {
        warm += 1;
      }
    }
    return { colours: seen.size, warm };
  }, png.toString("base64"));
}

async function main() {
  const started = Date.now();
  const browser = await chromium.launch({
    executablePath: args.chromium,
    headless: true,
    args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  const context = await browser.newContext({ viewport: { width: 1600, height: 1000 } });
  const page = await context.newPage();
  const consoleLines = [];
  page.on("console", (msg) => consoleLines.push(`${msg.type()}: ${msg.text()}`.slice(0, 300)));
  page.on("pageerror", (err) => consoleLines.push(`pageerror: ${err.message}`.slice(0, 300)));
  await page.goto(args.url);
  const status = {};
  let allOk = false;
  while (true) {
    allOk = true;
    for (const [id, criterion] of Object.entries(args.panels)) {
      if (status[id]?.ok) {
        continue;   // once a panel showed data it is not looked at again
      }
      const el = page.locator(panelSelector(id)).first();
      const entry = { ok: false, text: "", colours: 0, warm: 0 };
      if ((await el.count()) > 0) {
        entry.text = ((await el.innerText({ timeout: 2000 }).catch(() => "")) ?? "").slice(0, 400);
        if (criterion.text) {
          entry.ok = criterion.text.some((s) => entry.text.includes(s));
        }
        if (criterion.colours !== undefined || criterion.warm !== undefined) {
          const png = await el.screenshot({ timeout: 10000 }).catch(() => undefined);
          if (png) {
            Object.assign(entry, await colours(page, png));
            fs.writeFileSync(path.join(args.out_dir, `${id.replace(/[^A-Za-z0-9_]/g, "_")}.png`), png);
          }
          entry.ok = entry.colours >= (criterion.colours ?? 0) && entry.warm >= (criterion.warm ?? 0);
        }
      }
      if (entry.ok) {
        entry.t = (Date.now() - started) / 1000;
      }
      allOk = allOk && entry.ok;
      status[id] = entry;
    }
    const t = (Date.now() - started) / 1000;
    console.log(JSON.stringify({ t, panels: status }));
    if (allOk || t > args.deadline_s) { break; }
    await page.waitForTimeout(2000);
  }
  await page.screenshot({ path: path.join(args.out_dir, "page.png") }).catch(() => {});
  console.log(JSON.stringify({ done: true, ok: allOk, t: (Date.now() - started) / 1000,
    panels: status, console: consoleLines.slice(-40) }));
  await browser.close();
}

main().catch((err) => {
  console.log(JSON.stringify({ done: true, ok: false, error: String(err && err.stack || err) }));
  process.exit(1);
});
