#!/usr/bin/env node
// Checks the live viewer of a running `mcslam run --viewer` in headless Chromium.
//
//   node web/viewer/check-viewer.mjs URL SCREENSHOT_DIR
//
// Frames arrive, the map's point count grows, the trajectory is drawn, an occupancy snapshot
// with a grid and voxels arrives and the people's boxes do, the Grid, Voxels and People switches
// hide and show their layers, pause stops the frame counter and resume restarts it, the
// localisation switch is reflected, no console errors and nothing fetched from another origin.
// Saves viewer-live.png and viewer-map.png (all layers on).
// Exit status: 0 all checks passed, 1 a check failed, 2 wrong usage, 77 skipped (no Chromium at
// $CHROMIUM or /usr/bin/chromium, or no playwright-core in web/report/node_modules).
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const SKIP = 77;
const here = path.dirname(fileURLToPath(import.meta.url));
const CHROMIUM_ARGS = [
  '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
  '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
];

const [url, screenshotDir] = process.argv.slice(2);
if (!url || !screenshotDir) {
  console.error('usage: node check-viewer.mjs URL SCREENSHOT_DIR');
  process.exit(2);
}
const chromiumPath = process.env.CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(chromiumPath)) {
  console.log(`check-viewer: skipped: no Chromium at ${chromiumPath}`);
  process.exit(SKIP);
}
let chromium;
try {
  ({ chromium } = createRequire(path.join(here, '..', 'report', 'package.json'))('playwright-core'));
} catch {
  console.log('check-viewer: skipped: playwright-core is not installed (npm ci in web/report)');
  process.exit(SKIP);
}

const passed = [];
const failed = [];
const started = Date.now();
// detail: printed only when the check fails (what a failure needs to be understood).
function check(ok, message, detail) {
  if (!ok && detail) message += `; ${detail}`;
  (ok ? passed : failed).push(message);
  console.log(`${ok ? 'ok  ' : 'FAIL'}  ${message}  [${((Date.now() - started) / 1000).toFixed(1)} s]`);
}
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
const origin = new URL(url).origin;

// Pixels of the 3D view that are not its background.
function drawnPixels(page) {
  return page.evaluate(() => {
    const canvas = document.querySelector('canvas[data-view=map3d]');
    const gl = canvas.getContext('webgl2') || canvas.getContext('webgl');
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let n = 0;
    for (let i = 0; i < px.length; i += 4) {
      if (Math.abs(px[i] - 0xf3) + Math.abs(px[i + 1] - 0xf5) + Math.abs(px[i + 2] - 0xf8) > 30) n += 1;
    }
    return n;
  });
}

// Clicks "Fit view" (the whole map framed, as the first snapshot framed it) and waits for the view
// to be drawn: the pixel checks then do not depend on where the first snapshot put the view or
// on where following the camera has taken it.
async function fitView(page) {
  await page.click('button[data-control=fit]');
  await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
}

// Sets a layer switch (a click, as a user would) and waits for the view to be drawn again.
async function setLayer(page, name, on) {
  const box = page.locator(`input[data-control=layer-${name}]`);
  if ((await box.isChecked()) !== on) await box.click();
  await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
}

// The occupancy map's grid and voxels and the people's boxes arrive and are drawn; each switch
// hides its layer (the page's state, and the view loses the grid's and voxels' pixels) and shows
// it again. The camera is held still meanwhile (Follow camera off), so that the pixels compare.
async function checkLayers(page, viewer) {
  await page.waitForFunction(() => {
    const o = window.mcslamViewer.occupancy;
    return o && o.occupied > 0 && o.free > 0 && o.voxels > 0;
  }, null, { timeout: 30_000 }).catch(() => {});
  let v = await viewer();
  const o = v.occupancy || {};
  check(v.occupancyReceived >= 1 && o.width * o.height > 0 && o.occupied > 0 && o.free > 0,
    `an occupancy snapshot with a grid arrives (${v.occupancyReceived} received, ${o.width} x ${o.height} cells, ${o.occupied} occupied, ${o.free} free)`);
  check(o.voxels > 0 && o.voxels <= o.voxelsInMap, `with voxels (${o.voxels} of ${o.voxelsInMap})`);
  await page.waitForFunction(() => window.mcslamViewer.objectBoxesSeen > 0, null, { timeout: 20_000 }).catch(() => {});
  v = await viewer();
  check(v.objectBoxesSeen > 0, `the people's boxes arrive (at most ${v.objectBoxesSeen} at once)`);
  const labels = await page.evaluate(() => ['grid', 'voxels', 'people'].map((n) => {
    const box = document.querySelector(`input[data-control=layer-${n}]`);
    return box && box.checked && box.closest('label') ? box.closest('label').textContent.trim() : null;
  }));
  check(labels.join() === 'Grid,Voxels,People', `the three layer switches are there and on (${labels.join(', ')})`);
  check(v.layers && v.layers.grid.drawn && v.layers.voxels.drawn && v.layers.voxels.count === v.occupancy.voxels,
    `the grid and the voxels are drawn (${JSON.stringify(v.layers)})`);

  // The pixels are compared with the run paused (and what was in flight delivered), so that
  // only the switches change the view: a run going on grows the map and the trajectory.
  await page.locator('input[data-control=follow]').uncheck();
  await page.click('button[data-control=pause]');
  await page.waitForFunction(() => window.mcslamViewer.lastStats && window.mcslamViewer.lastStats.held, null, { timeout: 30_000 }).catch(() => {});
  await sleep(1500);
  await fitView(page);
  await setLayer(page, 'grid', true);
  const withLayers = await drawnPixels(page);
  for (const name of ['grid', 'voxels', 'people']) await setLayer(page, name, false);
  const without = await drawnPixels(page);
  v = await viewer();
  const hidden = ['grid', 'voxels', 'people'].every((n) => !v.layers[n].visible && !v.layers[n].drawn);
  check(hidden, `switched off, no layer is drawn (${JSON.stringify(v.layers)})`);
  check(withLayers - without > 1000, `the view loses the grid's and voxels' pixels (${withLayers} -> ${without}; a frame took ${Number(v.renderMs).toFixed(1)} ms to draw)`,
    `view ${JSON.stringify(v.view)}`);
  for (const name of ['grid', 'voxels', 'people']) await setLayer(page, name, true);
  const again = await drawnPixels(page);
  v = await viewer();
  check(v.layers.grid.drawn && v.layers.voxels.drawn && v.layers.people.visible
    && v.layers.people.drawn === (v.layers.people.count > 0), `switched on, they are drawn again (${JSON.stringify(v.layers)})`);
  check(again - without > 1000, `the view shows them again (${without} -> ${again})`, `view ${JSON.stringify(v.view)}`);
  await page.click('button[data-control=pause]');
  // A new occupancy snapshot keeps a hidden layer hidden.
  for (const name of ['grid', 'voxels']) await setLayer(page, name, false);
  const received = (await viewer()).occupancyReceived;
  await page.waitForFunction((n) => window.mcslamViewer.occupancyReceived > n, received, { timeout: 15_000 }).catch(() => {});
  v = await viewer();
  check(v.occupancyReceived > received && !v.layers.grid.drawn && !v.layers.voxels.drawn,
    `and stays off when the next snapshot arrives (${received} -> ${v.occupancyReceived})`);
  for (const name of ['grid', 'voxels']) await setLayer(page, name, true);
  await page.locator('input[data-control=follow]').check();
}

const browser = await chromium.launch({ executablePath: chromiumPath, args: CHROMIUM_ARGS, headless: true });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 900 } });
  const errors = [];
  const foreign = [];
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('request', (r) => {
    const u = r.url();
    if (!u.startsWith(origin) && !u.startsWith('ws://' + new URL(url).host) && !u.startsWith('blob:') && !u.startsWith('data:')) foreign.push(u);
  });
  await page.goto(url);
  await page.waitForFunction(() => document.body.dataset.ready === 'true', null, { timeout: 30_000 });
  check(true, 'the page connected and shows figures');

  const viewer = () => page.evaluate(() => ({ ...window.mcslamViewer, lastStats: window.mcslamViewer.lastStats }));
  // Frames arrive.
  await page.waitForFunction(() => window.mcslamViewer.framesReceived >= 3, null, { timeout: 30_000 }).catch(() => {});
  let v = await viewer();
  check(v.framesReceived >= 3, `frames arrive (${v.framesReceived})`);
  // The page shows a frame only once it is decoded: the image in the panel is always complete.
  await page.waitForFunction(() => window.mcslamViewer.framesShown >= 1, null, { timeout: 30_000 }).catch(() => {});
  const decoded = await page.evaluate(() => {
    const img = document.querySelector('img[data-view=frame]');
    return img && img.complete ? img.naturalWidth : 0;
  });
  check(decoded > 0, `the frame decodes (width ${decoded})`);

  // The map grows and the trajectory is drawn.
  await page.waitForFunction(() => window.mcslamViewer.mapsReceived >= 1 && window.mcslamViewer.mapPoints > 0, null, { timeout: 30_000 }).catch(() => {});
  const firstPoints = (await viewer()).mapPoints;
  await page.waitForFunction((n) => window.mcslamViewer.mapPoints > n, firstPoints, { timeout: 30_000 }).catch(() => {});
  v = await viewer();
  check(v.mapPoints > firstPoints && firstPoints > 0, `the map's point count grows (${firstPoints} -> ${v.mapPoints})`);
  check(v.trajectoryPoints >= 2, `the trajectory has points (${v.trajectoryPoints})`);
  await fitView(page);
  const mapPixels = await page.evaluate(() => {
    const canvas = document.querySelector('canvas[data-view=map3d]');
    const gl = canvas.getContext('webgl2') || canvas.getContext('webgl');
    if (!gl) return -1;
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let orange = 0, other = 0;
    for (let i = 0; i < px.length; i += 4) {
      const [r, g, b] = [px[i], px[i + 1], px[i + 2]];
      if (r > 200 && g > 90 && g < 160 && b < 60) orange += 1;  // the trajectory's #ff7f0e
      if (Math.abs(r - 0xf3) + Math.abs(g - 0xf5) + Math.abs(b - 0xf8) > 30) other += 1;
    }
    return { orange, other };
  });
  v = await viewer();
  check(mapPixels && mapPixels.orange > 20, `the trajectory is drawn in the 3D view (${mapPixels && mapPixels.orange} pixels)`,
    `view ${JSON.stringify(v.view)}, pose ${JSON.stringify(v.lastStats && v.lastStats.pose)}`);
  check(mapPixels && mapPixels.other > 500, `the 3D view is not blank (${mapPixels && mapPixels.other} pixels)`, `view ${JSON.stringify(v.view)}`);
  fs.mkdirSync(screenshotDir, { recursive: true });
  await checkLayers(page, viewer);
  await page.screenshot({ path: path.join(screenshotDir, 'viewer-live.png') });

  // Pause stops the frame counter; resume restarts it.
  await page.click('button[data-control=pause]');
  // The frame in flight when the pause arrives finishes first: "held" says the loop waits.
  await page.waitForFunction(() => window.mcslamViewer.lastStats && window.mcslamViewer.lastStats.held, null, { timeout: 30_000 }).catch(() => {});
  const pausedAt = (await viewer()).lastStats.done;
  await sleep(2000);
  v = await viewer();
  check(v.lastStats.paused && v.lastStats.held && v.lastStats.done === pausedAt, `pause stops the frame counter (${pausedAt} -> ${v.lastStats.done})`);
  const modeText = await page.textContent('[data-figure=mode]');
  check(modeText === 'paused', `the page says paused (${modeText})`);
  await page.click('button[data-control=pause]');
  await page.waitForFunction((n) => window.mcslamViewer.lastStats && window.mcslamViewer.lastStats.done > n + 3, pausedAt, { timeout: 20_000 }).catch(() => {});
  v = await viewer();
  check(!v.lastStats.paused && v.lastStats.done > pausedAt + 3, `resume restarts it (${pausedAt} -> ${v.lastStats.done})`);

  // Localisation only and back.
  await page.click('button[data-control=localize]');
  await page.waitForFunction(() => window.mcslamViewer.lastStats && window.mcslamViewer.lastStats.localize, null, { timeout: 10_000 }).catch(() => {});
  check((await viewer()).lastStats.localize === true, 'localisation only is switched on');
  await sleep(1000);
  await page.click('button[data-control=localize]');
  await page.waitForFunction(() => window.mcslamViewer.lastStats && !window.mcslamViewer.lastStats.localize, null, { timeout: 10_000 }).catch(() => {});
  check((await viewer()).lastStats.localize === false, 'and off again');

  // Orbit with the mouse changes the picture, then the map screenshot.
  const box = await page.locator('canvas[data-view=map3d]').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 120, box.y + box.height / 2 + 40, { steps: 8 });
  await page.mouse.up();
  await sleep(300);
  await page.locator('canvas[data-view=map3d]').screenshot({ path: path.join(screenshotDir, 'viewer-map.png') });

  check(errors.length === 0, `no console errors${errors.length ? `: ${errors.join(' | ')}` : ''}`);
  check(foreign.length === 0, `nothing fetched from elsewhere${foreign.length ? `: ${foreign.join(' ')}` : ''}`);
} catch (err) {
  check(false, `the check ran to its end (${err && err.message ? err.message : err})`);
} finally {
  await browser.close();
}
console.log(`check-viewer: ${passed.length} passed, ${failed.length} failed`);
process.exit(failed.length ? 1 : 0);
