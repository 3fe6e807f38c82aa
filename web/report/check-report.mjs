#!/usr/bin/env node
// Checks a report.html written by `mcslam bench` in headless Chromium.
//
//   node web/report/check-report.mjs REPORT.html SCREENSHOT.png
//
// Exit status: 0 all checks passed, 1 a check failed, 2 wrong usage,
// 77 skipped (no Chromium at $CHROMIUM or /usr/bin/chromium, or playwright-core
// is not installed in web/report/node_modules).
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath, pathToFileURL } from 'node:url';

const SKIP = 77;
const READY_TIMEOUT_MS = 60_000;
const here = path.dirname(fileURLToPath(import.meta.url));

const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  // WebGL without a GPU: ANGLE on the SwiftShader software renderer.
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
];

// ---------------------------------------------------------------- setup

const [reportArg, screenshotArg] = process.argv.slice(2);
if (!reportArg || !screenshotArg) {
  console.error('usage: node check-report.mjs REPORT.html SCREENSHOT.png');
  process.exit(2);
}
const reportPath = path.resolve(reportArg);
const screenshotPath = path.resolve(screenshotArg);

const chromiumPath = process.env.CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(chromiumPath)) {
  console.log(`check-report: skipped: no Chromium at ${chromiumPath} (set $CHROMIUM to another binary)`);
  process.exit(SKIP);
}
let chromium;
try {
  ({ chromium } = createRequire(path.join(here, 'package.json'))('playwright-core'));
} catch {
  console.log(`check-report: skipped: playwright-core is not installed (run npm ci in ${here})`);
  process.exit(SKIP);
}
if (!fs.existsSync(reportPath)) {
  console.log(`check-report: FAIL: no such file: ${reportPath}`);
  process.exit(1);
}

const passed = [];
const failed = [];
function check(ok, message) {
  (ok ? passed : failed).push(message);
  console.log(`${ok ? 'ok  ' : 'FAIL'}  ${message}`);
}

// ---------------------------------------------------------------- in-page helpers

// Counts the pixels of a 2D canvas: "data" pixels are coloured or very dark (chart
// series and bars; axes, grid and labels are grey), "changed" pixels differ from the
// top-left corner pixel (the background of the 3D view).
function canvasStats(selector) {
  const canvas = document.querySelector(selector);
  if (!canvas) return null;
  const w = canvas.width, h = canvas.height;
  if (!w || !h) return { w, h, data: 0, changed: 0 };
  const ctx = canvas.getContext('2d');
  const px = ctx.getImageData(0, 0, w, h).data;
  const bg = [px[0], px[1], px[2]];
  let data = 0, changed = 0;
  for (let i = 0; i < px.length; i += 4) {
    const r = px[i], g = px[i + 1], b = px[i + 2], a = px[i + 3];
    if (a > 0) {
      const max = Math.max(r, g, b), min = Math.min(r, g, b);
      if (max - min > 40 || max < 50) data++;
    }
    if (Math.abs(r - bg[0]) + Math.abs(g - bg[1]) + Math.abs(b - bg[2]) > 24) changed++;
  }
  return { w, h, data, changed };
}

// Keeps a copy of a canvas' pixels in the page (arg: [selector, key]) ...
function canvasKeep([selector, key]) {
  const canvas = document.querySelector(selector);
  window.__checkSnapshots = window.__checkSnapshots || {};
  window.__checkSnapshots[key] = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
}

// ... and counts the pixels that differ from that copy now.
function canvasDiff([selector, key]) {
  const canvas = document.querySelector(selector);
  const before = window.__checkSnapshots[key];
  const now = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
  if (now.length !== before.length) return { diff: canvas.width * canvas.height, total: canvas.width * canvas.height };
  let diff = 0;
  for (let i = 0; i < now.length; i += 4) {
    if (Math.abs(now[i] - before[i]) + Math.abs(now[i + 1] - before[i + 1]) + Math.abs(now[i + 2] - before[i + 2]) > 24) diff++;
  }
  return { diff, total: canvas.width * canvas.height };
}

function nextFrames() {
  return new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(() => resolve())));
}

// ---------------------------------------------------------------- expectations from the data

const validXyz = (p) => Array.isArray(p) && p.length >= 3 && p.slice(0, 3).every((v) => typeof v === 'number');

function expectationsOf(seq) {
  const results = (seq.results || []).filter((r) => r && !r.skipped);
  const trajs = results.filter((r) => r.trajectory && (r.trajectory.p || []).filter(validXyz).length >= 2);
  const gt = seq.groundtruth && (seq.groundtruth.p || []).filter(validXyz).length >= 2;
  return {
    trajectory: Boolean(gt || trajs.length),
    trajectoryData: trajs.length > 0,
    ate: trajs.some((r) => Array.isArray(r.trajectory.ate_error_m) && r.trajectory.ate_error_m.some((v) => typeof v === 'number')),
    timing: results.some((r) => Array.isArray(r.stages_ms) && r.stages_ms.some((s) => Array.isArray(s) && typeof s[1] === 'number')),
    map: Boolean(seq.map && ((seq.map.points || []).length >= 3 || (seq.map.keyframes || []).length || (seq.map.lines || []).length >= 6)),
    overlays: (seq.overlays || []).filter((o) => o && o.jpeg_base64).length,
    grid: Boolean(seq.grid && seq.grid.png_base64),
  };
}

// ---------------------------------------------------------------- run

const browser = await chromium.launch({ executablePath: chromiumPath, headless: true, args: CHROMIUM_ARGS });
let exitCode = 1;
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 900 }, deviceScaleFactor: 1 });
  const page = await context.newPage();
  const consoleErrors = [];
  const consoleWarnings = [];
  const pageErrors = [];
  const remoteRequests = [];
  page.on('console', (msg) => {
    if (msg.type() === 'error') consoleErrors.push(msg.text());
    if (msg.type() === 'warning') consoleWarnings.push(msg.text());
  });
  page.on('pageerror', (err) => pageErrors.push(String(err && err.stack ? err.stack : err)));
  page.on('request', (req) => {
    const scheme = req.url().split(':', 1)[0].toLowerCase();
    if (!['file', 'data', 'blob'].includes(scheme)) remoteRequests.push(req.url());
  });

  const started = Date.now();
  await page.goto(pathToFileURL(reportPath).href, { waitUntil: 'load' });
  let ready = true;
  try {
    await page.waitForSelector('body[data-ready="true"]', { state: 'attached', timeout: READY_TIMEOUT_MS });
  } catch {
    ready = false;
  }
  check(ready, `page became ready (body[data-ready=true]) in ${((Date.now() - started) / 1000).toFixed(1)} s`);

  const data = await page.evaluate(() => {
    try {
      return JSON.parse(document.getElementById('mcslam-data').textContent);
    } catch {
      return null;
    }
  });
  check(data !== null, 'data JSON in #mcslam-data parses');

  if (ready && data) {
    const configs = (data.configs || []).map((c) => c.name);
    const sequences = data.sequences || [];
    const mapViews = [];
    for (let i = 0; i < sequences.length; i++) {
      const seq = sequences[i];
      const name = `[${seq.name}]`;
      const sel = `section.sequence[data-seq="${i}"]`;
      const expect = expectationsOf(seq);
      check(await page.locator(sel).count() === 1, `${name} has a section`);

      const rows = await page.$$eval(`${sel} table.ablation tbody tr[data-config]`, (trs) => trs.map((tr) => tr.dataset.config));
      check(rows.length === configs.length && rows.every((c, k) => c === configs[k]),
        `${name} ablation table has one row per config (${rows.length}/${configs.length}: ${rows.join(', ')})`);

      const charts = [];
      if (expect.trajectory) charts.push('trajectory-top', 'trajectory-x', 'trajectory-y', 'trajectory-z');
      if (expect.ate) charts.push('ate-time');
      if (expect.timing) charts.push('timing');
      for (const kind of charts) {
        const stats = await page.evaluate(canvasStats, `${sel} canvas[data-chart="${kind}"]`);
        const min = 100;
        check(stats !== null && stats.w > 0 && stats.data >= min,
          `${name} chart ${kind} ${stats ? `is ${stats.w}x${stats.h} with ${stats.data} data pixels (need ${min})` : 'is missing'}`);
      }
      const skippedCharts = ['trajectory', 'ate', 'timing'].filter((k) => !expect[k]);
      if (skippedCharts.length) {
        const notes = await page.locator(`${sel} .part .note`).count();
        check(notes >= skippedCharts.length, `${name} shows a message instead of the ${skippedCharts.join(', ')} chart(s) absent from the data`);
      }

      if (expect.map) {
        const canvasSel = `${sel} canvas[data-view="map3d"]`;
        const before = await page.evaluate(canvasStats, canvasSel);
        const total = before ? before.w * before.h : 0;
        check(before !== null && before.changed > total * 0.005,
          `${name} 3D map ${before ? `is ${before.w}x${before.h} with ${before.changed} non-background pixels` : 'canvas is missing'}`);
        if (before) {
          await page.evaluate(canvasKeep, [canvasSel, `map${i}`]);
          mapViews.push({ name, canvasSel, key: `map${i}` });
        }
      } else {
        const absent = await page.locator(`${sel} canvas[data-view="map3d"]`).count();
        check(absent === 0, `${name} has no map in the data and no 3D view`);
      }

      if (expect.grid) {
        const grid = await page.$$eval(`${sel} img[data-grid]`, (els) => els.map((img) => ({ ok: img.complete && img.naturalWidth > 0, w: img.naturalWidth, h: img.naturalHeight })));
        check(grid.length === 1 && grid[0].ok, `${name} occupancy grid decoded (${grid.map((g) => `${g.w}x${g.h}`).join(', ') || 'missing'})`);
      } else {
        const absent = await page.locator(`${sel} img[data-grid]`).count();
        check(absent === 0, `${name} has no grid in the data and shows none`);
      }

      if (expect.overlays) {
        const imgs = await page.$$eval(`${sel} img[data-overlay]`, (els) => els.map((img) => ({ ok: img.complete && img.naturalWidth > 0, w: img.naturalWidth })));
        check(imgs.length === expect.overlays && imgs.every((im) => im.ok),
          `${name} ${imgs.length}/${expect.overlays} annotated frames decoded (naturalWidth ${imgs.map((im) => im.w).join(', ')})`);
      }
    }

    const failedRows = await page.locator('#failed-runs table tbody tr').count();
    const failedExpected = (data.failed_runs || []).length;
    check(failedRows === failedExpected, `failed runs list has ${failedRows}/${failedExpected} rows`);
    if (typeof data.markdown === 'string' && data.markdown.trim()) {
      const md = await page.locator('#markdown pre').textContent();
      check(md === data.markdown, 'raw Markdown is shown verbatim');
    }

    const overflow = await page.evaluate(() => document.documentElement.scrollWidth - document.documentElement.clientWidth);
    check(overflow <= 1, `no horizontal overflow at 1280 px (${overflow} px)`);
    await page.evaluate(() => window.scrollTo(0, 0));
    await page.evaluate(nextFrames);
    await page.screenshot({ path: screenshotPath, fullPage: true });
    console.log(`      screenshot: ${screenshotPath}`);

    // Dragging over each 3D view must change the picture (it rotates). Done after the
    // screenshot, so that shows the default views.
    for (const view of mapViews) {
      const canvas = page.locator(view.canvasSel);
      await canvas.scrollIntoViewIfNeeded();
      const box = await canvas.boundingBox();
      const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
      await page.mouse.move(cx, cy);
      await page.mouse.down();
      await page.mouse.move(cx + 140, cy + 50, { steps: 8 });
      await page.mouse.up();
      await page.evaluate(nextFrames);
      const { diff, total } = await page.evaluate(canvasDiff, [view.canvasSel, view.key]);
      check(diff > total * 0.01, `${view.name} dragging rotates the 3D map (${diff} of ${total} pixels changed)`);
    }

    await page.setViewportSize({ width: 390, height: 844 });
    await page.evaluate(nextFrames);
    const narrow = await page.evaluate(() => document.documentElement.scrollWidth - document.documentElement.clientWidth);
    check(narrow <= 1, `no horizontal overflow at 390 px (${narrow} px)`);
  } else {
    await page.screenshot({ path: screenshotPath, fullPage: true }).catch(() => {});
  }

  // Warnings are listed but do not fail the check. Chromium's performance hints (GPU
  // readback, and getImageData calls that come from this script) are only counted.
  const benign = /GPU stall due to ReadPixels|willReadFrequently/;
  const warningCounts = new Map();
  let benignCount = 0;
  for (const w of consoleWarnings) {
    if (benign.test(w)) benignCount++;
    else warningCounts.set(w, (warningCounts.get(w) || 0) + 1);
  }
  for (const [w, n] of warningCounts) console.log(`note  console warning${n > 1 ? ` (${n}x)` : ''}: ${w}`);
  if (benignCount) console.log(`note  ${benignCount} Chromium performance hint(s) on the console (readback), ignored`);
  check(pageErrors.length === 0, `no uncaught page errors${pageErrors.length ? `: ${pageErrors.join(' | ')}` : ''}`);
  check(consoleErrors.length === 0, `no console errors${consoleErrors.length ? `: ${consoleErrors.join(' | ')}` : ''}`);
  check(remoteRequests.length === 0, `nothing fetched from outside the file${remoteRequests.length ? `: ${remoteRequests.join(' ')}` : ''}`);
  exitCode = failed.length ? 1 : 0;
} catch (err) {
  check(false, `the check itself failed: ${err && err.stack ? err.stack : err}`);
  exitCode = 1;
} finally {
  await browser.close();
}

if (failed.length) {
  console.log('\nFailed checks:');
  for (const f of failed) console.log(`  - ${f}`);
}
console.log(`check-report: ${passed.length} passed, ${failed.length} failed`);
process.exit(exitCode);
