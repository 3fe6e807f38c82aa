// The live viewer of `mcslam run --viewer`: the current frame with its overlay, the 3D map, live
// figures and the run's controls, fed by the WebSocket at /ws (see docs/viewer.md).
//
// Messages from the server: text JSON {type: "hello" | "stats"}, and binary ones whose first byte
// is the type: 1 a frame (uint32 frame id at byte 4, then the JPEG), 2 a map snapshot and 3 an
// occupancy snapshot (uint32 length of a JSON header at byte 4, the header, then the arrays it
// counts, each 4-byte aligned).
// To the server: {"cmd": "pause" | "resume" | "localize" | "map"}.
import css from './style.css';
import { h } from '../../shared/dom.js';
import { isNum, num } from '../../shared/format.js';
import { LiveMap, LAYERS } from './live-map.js';
import { GRID_OCCUPIED, GRID_FREE, DYNAMIC_BOX_COLOR, CONSTRAINED_BOX_COLOR } from './occupancy-layers.js';

const rgba = ([r, g, b, a]) => `rgba(${r}, ${g}, ${b}, ${(a / 255).toFixed(2)})`;

const state = {
  framesReceived: 0,
  framesShown: 0,
  mapsReceived: 0,
  statsReceived: 0,
  lastStats: null,
  mapPoints: 0,
  trajectoryPoints: 0,
  occupancyReceived: 0,
  occupancy: null,       // the newest occupancy snapshot's counts
  objectBoxes: 0,        // moving objects' boxes of the newest frame
  objectBoxesSeen: 0,    // the most at once so far
  layers: null,          // what each layer of the 3D map draws (LiveMap.layerState)
  renderMs: null,        // the 3D map's last frame, on the page's thread
  view: null,            // where the 3D map's view looks from and at (LiveMap.viewState)
  connected: false,
};
// Read by the browser test (web/viewer/check-viewer.mjs, run by tests/app/viewer_browser.sh).
window.mcslamViewer = state;

document.head.append(h('style', {}, css));

// ---------------------------------------------------------------- layout

const status = h('span', { class: 'status', dataset: { connected: 'false' } }, 'connecting…');
const pauseButton = h('button', { type: 'button', class: 'button', dataset: { control: 'pause' }, 'aria-pressed': 'false' }, 'Pause');
const localizeButton = h('button', { type: 'button', class: 'button', dataset: { control: 'localize' }, 'aria-pressed': 'false' }, 'Localisation only');
const followBox = h('input', { type: 'checkbox', checked: true, dataset: { control: 'follow' } });
const fitButton = h('button', { type: 'button', class: 'button', dataset: { control: 'fit' }, title: 'Frame the whole map' }, 'Fit view');
// The 3D map's layers, each a switch kept as set while the run goes on.
const LAYER_LABELS = { grid: 'Grid', voxels: 'Voxels', people: 'People' };
const layerBoxes = {};
for (const name of LAYERS) layerBoxes[name] = h('input', { type: 'checkbox', checked: true, dataset: { control: `layer-${name}` } });
const header = h('header', {},
  h('h1', {}, 'mcslam live'), status, pauseButton, localizeButton,
  fitButton, h('label', { class: 'control' }, followBox, ' Follow camera'),
  LAYERS.map((name) => h('label', { class: 'control' }, layerBoxes[name], ` ${LAYER_LABELS[name]}`)));

let frameImage = h('img', { alt: 'current frame with its overlay', dataset: { view: 'frame' } });
const FIGURES = [
  ['frame', 'Frame'], ['state', 'State'], ['fps', 'Frames / s'], ['tracking', 'Tracking ms'],
  ['detector', 'Detector passes / s'], ['box-age', 'Box age (frames)'], ['dynamic', 'Dynamic objects'],
  ['constrained', 'Constrained objects'], ['loops', 'Loops closed'], ['keyframes', 'Keyframes'],
  ['map-points', 'Map points'], ['mode', 'Mode'],
];
const figureValues = {};
const figures = h('div', { class: 'figures' }, FIGURES.map(([key, label]) => {
  figureValues[key] = h('div', { class: 'value', dataset: { figure: key } }, '–');
  return h('div', { class: 'figure' }, h('div', { class: 'label' }, label), figureValues[key]);
}));
const plotCanvas = h('canvas', { dataset: { view: 'tracking-plot' }, width: '600', height: '90' });
const framePanel = h('section', { class: 'panel frame' }, h('h2', {}, 'Current frame'), frameImage,
  h('p', { class: 'hint legend' },
    h('span', {}, h('i', { style: { background: '#00c800' } }), 'static points'),
    h('span', {}, h('i', { style: { background: '#e60000' } }), 'lines, dynamic boxes'),
    h('span', {}, h('i', { style: { background: '#ffdc00' } }), 'constrained'),
    h('span', {}, h('i', { style: { background: '#969696' } }), 'on movers')),
  figures,
  h('div', { class: 'plot' }, h('h2', {}, 'Tracking time (ms), last frames'), plotCanvas));

const mapCanvas = h('canvas', { dataset: { view: 'map3d' }, role: 'img', 'aria-label': '3D map' });
const mapStage = h('div', { class: 'map-stage' }, mapCanvas);
const mapHint = h('p', { class: 'hint' }, 'Drag to rotate, right-drag or shift-drag to pan, wheel to zoom.');
const mapPanel = h('section', { class: 'panel' }, h('h2', {}, '3D map'), mapStage,
  h('p', { class: 'hint legend' },
    h('span', {}, h('i', { style: { background: '#ff7f0e' } }), 'trajectory'),
    h('span', {}, h('i', { style: { background: '#9aa5b1' } }), 'ground truth'),
    h('span', {}, h('i', { style: { background: '#7b2cbf' } }), 'keyframes'),
    h('span', {}, h('i', { style: { background: '#0a7d2c' } }), 'camera'),
    h('span', {}, h('i', { style: { background: rgba(GRID_OCCUPIED) } }), 'grid: occupied'),
    h('span', {}, h('i', { style: { background: rgba(GRID_FREE) } }), 'free'),
    h('span', {}, h('i', { style: { background: DYNAMIC_BOX_COLOR } }), 'people (dynamic)'),
    h('span', {}, h('i', { style: { background: CONSTRAINED_BOX_COLOR } }), 'constrained movers')),
  mapHint);
document.body.append(header, h('main', {}, framePanel, mapPanel));

let map = null;
try {
  map = new LiveMap(mapCanvas, mapStage);
} catch (err) {
  console.warn('mcslam viewer: 3D map view unavailable:', err);
  mapStage.replaceWith(h('p', { class: 'hint' }, `The 3D map needs WebGL, which is not available here (${err && err.message ? err.message : err}).`));
}
followBox.addEventListener('change', () => map && map.setFollow(followBox.checked));
fitButton.addEventListener('click', () => {
  if (map) map.fitToMap();
  refreshLayers();
});
function refreshLayers() {
  if (map) {
    state.layers = map.layerState();
    state.renderMs = map.renderMs;
    state.view = map.viewState();
  }
}
for (const name of LAYERS) {
  layerBoxes[name].addEventListener('change', () => {
    if (map) map.setLayerVisible(name, layerBoxes[name].checked);
    refreshLayers();
  });
}
refreshLayers();

// ---------------------------------------------------------------- connection

let socket = null;
function send(cmd) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({ cmd }));
}
pauseButton.addEventListener('click', () => send(state.lastStats && state.lastStats.paused ? 'resume' : 'pause'));
localizeButton.addEventListener('click', () => send(state.lastStats && state.lastStats.localize ? 'map' : 'localize'));

function connect() {
  const scheme = location.protocol === 'https:' ? 'wss://' : 'ws://';
  socket = new WebSocket(`${scheme}${location.host}/ws`);
  socket.binaryType = 'arraybuffer';
  socket.addEventListener('open', () => {
    state.connected = true;
    status.dataset.connected = 'true';
    status.textContent = 'connected';
  });
  socket.addEventListener('close', () => {
    state.connected = false;
    status.dataset.connected = 'false';
    const finished = state.lastStats && state.lastStats.finished;
    status.textContent = finished ? 'the run has ended' : 'disconnected (is the run still going?)';
    if (!finished) setTimeout(connect, 2000);
  });
  socket.addEventListener('message', (event) => {
    try {
      if (typeof event.data === 'string') onText(JSON.parse(event.data));
      else onBinary(event.data);
    } catch (err) {
      console.warn('mcslam viewer: a message could not be read:', err);
    }
  });
}

function onText(message) {
  if (message.type === 'hello') {
    document.title = `mcslam live — ${message.sequence || ''}`;
    if (map && message.groundtruth) map.setGroundTruth(Float32Array.from(message.groundtruth));
  } else if (message.type === 'stats') {
    state.statsReceived += 1;
    state.lastStats = message;
    showStats(message);
    if (map) map.setPose(message.pose);
    const boxes = Array.isArray(message.object_boxes) ? message.object_boxes : [];
    state.objectBoxes = boxes.length;
    state.objectBoxesSeen = Math.max(state.objectBoxesSeen, boxes.length);
    if (map) map.setObjectBoxes(boxes);
    refreshLayers();
    document.body.dataset.ready = 'true';
  }
}

// A frame replaces the one shown only once it is decoded, so the panel never shows a half-loaded
// image. A frame that arrives while another decodes waits as the newest one (an older waiting
// frame is dropped): on a loaded machine the panel shows fewer frames, never none.
let decoding = false;
let waiting = null;
function showFrame(frame) {
  if (decoding) {
    if (waiting) URL.revokeObjectURL(waiting.url);
    waiting = frame;
    return;
  }
  decoding = true;
  const next = h('img', { alt: frameImage.alt, dataset: { view: 'frame', frameId: String(frame.id) } });
  next.src = frame.url;
  next.decode().then(() => {
    URL.revokeObjectURL(frameImage.src);
    frameImage.replaceWith(next);
    frameImage = next;
    state.framesShown += 1;
  }, () => URL.revokeObjectURL(frame.url)).finally(() => {
    decoding = false;
    const after = waiting;
    waiting = null;
    if (after) showFrame(after);
  });
}

function onBinary(buffer) {
  const type = new Uint8Array(buffer, 0, 1)[0];
  if (type === 1) {
    const url = URL.createObjectURL(new Blob([buffer.slice(8)], { type: 'image/jpeg' }));
    showFrame({ url, id: new DataView(buffer).getUint32(4, true) });
    state.framesReceived += 1;
  } else if (type === 2) {
    const decoded = decodeMap(buffer);
    state.mapsReceived += 1;
    state.mapPoints = decoded.header.points_in_map;
    state.trajectoryPoints = decoded.header.trajectory;
    figureValues['map-points'].textContent = String(decoded.header.points_in_map);
    figureValues.loops.textContent = String(decoded.header.loops_closed);
    if (map) map.setMap(decoded);
  } else if (type === 3) {
    const decoded = decodeOccupancy(buffer);
    state.occupancyReceived += 1;
    state.occupancy = occupancyCounts(decoded);
    if (map) map.setOccupancy(decoded);
    refreshLayers();
  }
}

// The header and a reader of the arrays after it, each from a 4-byte boundary.
function messageReader(buffer) {
  const length = new DataView(buffer).getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, length)));
  let offset = 8 + length;
  const take = (Type, count) => {
    offset = Math.ceil(offset / 4) * 4;
    const array = new Type(buffer, offset, count);
    offset += count * Type.BYTES_PER_ELEMENT;
    return array;
  };
  return { header, take };
}

function decodeOccupancy(buffer) {
  const { header, take } = messageReader(buffer);
  const T = take(Float32Array, 16);
  const cells = take(Int8Array, header.width * header.height);
  const centres = take(Float32Array, 3 * header.voxels);
  const sizes = take(Float32Array, header.voxels);
  const rgb = take(Uint8Array, 3 * header.voxels);
  return {
    header,
    grid: { width: header.width, height: header.height, resolution: header.resolution, T, cells },
    voxels: { count: header.voxels, centres, sizes, rgb },
  };
}

function occupancyCounts({ header, grid }) {
  let occupied = 0;
  let free = 0;
  for (const v of grid.cells) {
    if (v >= 50) occupied += 1;
    else if (v >= 0) free += 1;
  }
  return {
    version: header.version, width: header.width, height: header.height, occupied, free,
    voxels: header.voxels, voxelsInMap: header.voxels_in_map,
  };
}

function decodeMap(buffer) {
  const { header, take } = messageReader(buffer);
  const points = take(Float32Array, 3 * header.points);
  const colors = take(Uint8Array, 3 * header.points);
  const lines = take(Float32Array, 6 * header.lines);
  const keyframeFlat = take(Float32Array, 3 * header.keyframes);
  const trajectory = take(Float32Array, 3 * header.trajectory);
  const planeCorners = header.planes.reduce((n, p) => n + p.corners, 0);
  const hullFlat = take(Float32Array, 3 * planeCorners);
  const keyframes = [];
  for (let i = 0; i < header.keyframes; i++) keyframes.push(Array.from(keyframeFlat.subarray(3 * i, 3 * i + 3)));
  let k = 0;
  const planes = header.planes.map((p) => {
    const hull = [];
    for (let i = 0; i < p.corners; i++, k++) hull.push(Array.from(hullFlat.subarray(3 * k, 3 * k + 3)));
    return { hull };
  });
  return { header, points, colors, lines, keyframes, planes, trajectory };
}

// ---------------------------------------------------------------- figures

function showStats(s) {
  const total = isNum(s.total) && s.total > 0 ? ` / ${s.total}` : '';
  figureValues.frame.textContent = `${s.done}${total}`;
  figureValues.state.textContent = s.state;
  figureValues.fps.textContent = num(s.fps, 'fps');
  figureValues.tracking.textContent = num(s.tracking_ms, 'ms');
  figureValues.detector.textContent = isNum(s.detector_hz) ? s.detector_hz.toFixed(1) : '–';
  figureValues['box-age'].textContent = s.box_age >= 0 ? String(s.box_age) : '–';
  figureValues.dynamic.textContent = String(s.dynamic_objects);
  figureValues.constrained.textContent = String(s.constrained_objects);
  figureValues.keyframes.textContent = String(s.keyframes_inserted);
  figureValues.mode.textContent = s.finished ? 'finished' : s.paused ? (s.held ? 'paused' : 'pausing') : s.localize ? 'localisation only' : 'mapping';
  pauseButton.textContent = s.paused ? 'Resume' : 'Pause';
  pauseButton.setAttribute('aria-pressed', String(Boolean(s.paused)));
  localizeButton.setAttribute('aria-pressed', String(Boolean(s.localize)));
  pauseButton.disabled = localizeButton.disabled = Boolean(s.finished);
  drawPlot(Array.isArray(s.tracking_recent) ? s.tracking_recent : []);
}

function drawPlot(values) {
  const ctx = plotCanvas.getContext('2d');
  const w = plotCanvas.width;
  const hgt = plotCanvas.height;
  ctx.fillStyle = '#f4f6f9';
  ctx.fillRect(0, 0, w, hgt);
  if (values.length < 2) return;
  const max = Math.max(10, ...values) * 1.1;
  ctx.strokeStyle = '#1f77b4';
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  values.forEach((v, i) => {
    const x = (i / (values.length - 1)) * (w - 40) + 36;
    const y = hgt - 4 - (v / max) * (hgt - 10);
    if (i === 0) ctx.moveTo(x, y);
    else ctx.lineTo(x, y);
  });
  ctx.stroke();
  ctx.fillStyle = '#5b6b7d';
  ctx.font = '10px sans-serif';
  ctx.fillText(`${max.toFixed(0)}`, 2, 12);
  ctx.fillText('0', 2, hgt - 4);
}

connect();
