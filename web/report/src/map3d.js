// 3D map view (three.js): points, line segments, planes and the keyframe trajectory,
// with orbit controls.
//
// All map views share one WebGL renderer whose canvas is not in the page: a view
// renders into it and copies the picture onto its own 2D canvas. This keeps a single
// WebGL context however many sequences the report has (browsers allow only a few),
// and the visible canvas can always be read back.
import {
  WebGLRenderer, Scene, PerspectiveCamera, BufferGeometry, Float32BufferAttribute, BufferAttribute,
  Points, PointsMaterial, LineSegments, LineBasicMaterial, Line, LineLoop, Mesh, MeshBasicMaterial,
  DoubleSide, Color, Vector2, Vector3, Group, AxesHelper, ColorManagement, LinearSRGBColorSpace,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { h, note } from './dom.js';
import { isNum } from './format.js';

// Colours in the data are shown as they are (no sRGB/linear conversion).
ColorManagement.enabled = false;

const BACKGROUND = '#f3f5f8';
const POINT_COLOR = '#56657a';
const LINE_COLOR = '#d62728';
const KEYFRAME_COLOR = '#7b2cbf';
const PLANE_COLORS = ['#1f77b4', '#2ca02c', '#ff7f0e', '#17becf', '#bcbd22', '#e377c2', '#8c564b', '#9467bd'];

// The direction the camera looks from, for each choice of "up". The map frame is
// usually the first camera's frame (x right, y down, z forward), hence "-y" by default.
const UP_CHOICES = {
  '-y': { label: '−y (camera frame)', up: [0, -1, 0], from: [0.35, -0.75, -1] },
  '+z': { label: '+z', up: [0, 0, 1], from: [0.35, -1, 0.75] },
  '+y': { label: '+y', up: [0, 1, 0], from: [0.35, 0.75, 1] },
  '-z': { label: '−z', up: [0, 0, -1], from: [0.35, -1, -0.75] },
};

// ---------------------------------------------------------------- shared renderer

let shared = null;

function sharedRenderer() {
  if (shared) return shared;
  try {
    const canvas = document.createElement('canvas');
    const attributes = { alpha: false, antialias: true, depth: true, stencil: false, preserveDrawingBuffer: true };
    const context = canvas.getContext('webgl2', attributes);
    if (!context) throw new Error('WebGL 2 is not available in this browser');
    const renderer = new WebGLRenderer({ canvas, context, ...attributes });
    renderer.outputColorSpace = LinearSRGBColorSpace;
    shared = { renderer };
  } catch (err) {
    shared = { error: err };
  }
  return shared;
}

// ---------------------------------------------------------------- geometry from data

function flatTriples(values) {
  if (!Array.isArray(values)) return new Float32Array(0);
  const n = Math.floor(values.length / 3);
  const out = new Float32Array(n * 3);
  let k = 0;
  for (let i = 0; i < n; i++) {
    const x = values[3 * i], y = values[3 * i + 1], z = values[3 * i + 2];
    if (isNum(x) && isNum(y) && isNum(z)) {
      out[k++] = x;
      out[k++] = y;
      out[k++] = z;
    }
  }
  return out.subarray(0, k);
}

function pointCloud(map) {
  const raw = Array.isArray(map.points) ? map.points : [];
  const n = Math.floor(raw.length / 3);
  const colors = Array.isArray(map.colors) && map.colors.length >= n * 3 ? map.colors : null;
  const pos = new Float32Array(n * 3);
  const col = colors ? new Uint8Array(n * 3) : null;
  let k = 0;
  for (let i = 0; i < n; i++) {
    const x = raw[3 * i], y = raw[3 * i + 1], z = raw[3 * i + 2];
    if (!(isNum(x) && isNum(y) && isNum(z))) continue;
    pos[3 * k] = x;
    pos[3 * k + 1] = y;
    pos[3 * k + 2] = z;
    if (col) {
      for (let c = 0; c < 3; c++) col[3 * k + c] = Math.max(0, Math.min(255, Number(colors[3 * i + c]) || 0));
    }
    k++;
  }
  if (!k) return null;
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new BufferAttribute(pos.subarray(0, 3 * k), 3));
  if (col) geometry.setAttribute('color', new BufferAttribute(col.subarray(0, 3 * k), 3, true));
  const material = new PointsMaterial({
    size: 2, sizeAttenuation: false, vertexColors: Boolean(col), color: col ? 0xffffff : POINT_COLOR,
  });
  return { object: new Points(geometry, material), count: k, positions: pos.subarray(0, 3 * k) };
}

function lineSegments(map) {
  const flat = Array.isArray(map.lines) ? map.lines : [];
  const pos = [];
  for (let i = 0; i + 5 < flat.length; i += 6) {
    const seg = flat.slice(i, i + 6);
    if (seg.every(isNum)) pos.push(...seg);
  }
  if (!pos.length) return null;
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new Float32BufferAttribute(pos, 3));
  return { object: new LineSegments(geometry, new LineBasicMaterial({ color: LINE_COLOR })), count: pos.length / 6, positions: pos };
}

function planes(map) {
  const group = new Group();
  const positions = [];
  let count = 0;
  (Array.isArray(map.planes) ? map.planes : []).forEach((plane, i) => {
    const hull = plane && Array.isArray(plane.hull)
      ? plane.hull.filter((p) => Array.isArray(p) && p.length >= 3 && isNum(p[0]) && isNum(p[1]) && isNum(p[2]))
      : [];
    if (hull.length < 3) return;
    const color = new Color(PLANE_COLORS[i % PLANE_COLORS.length]);
    // The hull is convex, so a triangle fan around its first vertex covers it.
    const tri = [];
    for (let j = 1; j + 1 < hull.length; j++) tri.push(...hull[0], ...hull[j], ...hull[j + 1]);
    const fill = new BufferGeometry();
    fill.setAttribute('position', new Float32BufferAttribute(tri, 3));
    group.add(new Mesh(fill, new MeshBasicMaterial({
      color, transparent: true, opacity: 0.22, side: DoubleSide, depthWrite: false,
    })));
    const outline = new BufferGeometry();
    outline.setAttribute('position', new Float32BufferAttribute(hull.flat(), 3));
    group.add(new LineLoop(outline, new LineBasicMaterial({ color })));
    hull.forEach((p) => positions.push(p[0], p[1], p[2]));
    count += 1;
  });
  return count ? { object: group, count, positions } : null;
}

function keyframePath(map) {
  const kf = Array.isArray(map.keyframes)
    ? map.keyframes.filter((p) => Array.isArray(p) && p.length >= 3 && isNum(p[0]) && isNum(p[1]) && isNum(p[2]))
    : [];
  if (!kf.length) return null;
  const flat = kf.flatMap((p) => [p[0], p[1], p[2]]);
  const group = new Group();
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new Float32BufferAttribute(flat, 3));
  if (kf.length > 1) group.add(new Line(geometry, new LineBasicMaterial({ color: KEYFRAME_COLOR })));
  group.add(new Points(geometry, new PointsMaterial({ size: 5, sizeAttenuation: false, color: KEYFRAME_COLOR })));
  return { object: group, count: kf.length, positions: flat };
}

// ---------------------------------------------------------------- framing

// Bounds that ignore the 1 % most extreme point and line-endpoint coordinates on each side
// (stray landmarks), plus the planes and keyframes in full.
function sceneBounds(parts) {
  const min = [Infinity, Infinity, Infinity];
  const max = [-Infinity, -Infinity, -Infinity];
  const include = (x, axis) => {
    if (x < min[axis]) min[axis] = x;
    if (x > max[axis]) max[axis] = x;
  };
  for (const key of ['points', 'lines']) {
    const pos = parts[key] && parts[key].positions;
    if (!pos || pos.length < 3) continue;
    const n = Math.floor(pos.length / 3);
    for (let axis = 0; axis < 3; axis++) {
      const values = new Float32Array(n);
      for (let i = 0; i < n; i++) values[i] = pos[3 * i + axis];
      values.sort();
      include(values[Math.floor(0.01 * (n - 1))], axis);
      include(values[Math.ceil(0.99 * (n - 1))], axis);
    }
  }
  for (const key of ['planes', 'keyframes']) {
    const pos = parts[key] && parts[key].positions;
    if (!pos) continue;
    for (let i = 0; i + 2 < pos.length; i += 3) for (let axis = 0; axis < 3; axis++) include(pos[i + axis], axis);
  }
  if (!Number.isFinite(min[0])) return null;
  const center = new Vector3((min[0] + max[0]) / 2, (min[1] + max[1]) / 2, (min[2] + max[2]) / 2);
  const radius = Math.max(0.05, 0.5 * Math.hypot(max[0] - min[0], max[1] - min[1], max[2] - min[2]));
  return { center, radius };
}

// ---------------------------------------------------------------- the view

export function mapPart(seq, seqIndex) {
  const map = seq.map;
  if (!map) return { element: note('No map for this sequence.'), mount: null };
  const parts = {
    points: pointCloud(map),
    lines: lineSegments(map),
    planes: planes(map),
    keyframes: keyframePath(map),
  };
  const bounds = sceneBounds(parts);
  if (!bounds) return { element: note('The map of this sequence is empty.'), mount: null };

  const canvas = h('canvas', { class: 'map-canvas', dataset: { view: 'map3d', seq: String(seqIndex) }, role: 'img', 'aria-label': '3D map' });
  const stage = h('div', { class: 'map-stage' }, canvas);
  const toggles = h('div', { class: 'map-toggles' });
  const controlsBar = h('div', { class: 'toolbar map-toolbar' }, toggles);
  const counts = [
    parts.points ? `${parts.points.count.toLocaleString('en-US')} points${map.colors ? ' (RGB)' : ''}` : 'no points',
    parts.lines ? `${parts.lines.count} lines` : 'no lines',
    parts.planes ? `${parts.planes.count} planes` : 'no planes',
    parts.keyframes ? `${parts.keyframes.count} keyframes` : 'no keyframes',
  ].join(' · ');
  const source = [map.config ? `config ${map.config}` : null, map.run ? `run ${map.run}` : null].filter(Boolean).join(', ');
  const element = h('div', { class: 'map3d' }, controlsBar, stage,
    h('p', { class: 'hint' }, `${counts}${source ? ` — from ${source}` : ''}. Drag to rotate, right-drag or shift-drag to pan, wheel to zoom.`));

  const mount = () => {
    const { renderer, error } = sharedRenderer();
    if (!renderer) {
      console.warn('mcslam report: 3D map view unavailable:', error);
      stage.replaceWith(note(`The 3D map view needs WebGL, which is not available here (${error && error.message ? error.message : error}).`, 'error'));
      controlsBar.remove();
      return [];
    }
    return [new MapView({ renderer, canvas, stage, toggles, controlsBar, parts, bounds })];
  };
  return { element, mount };
}

class MapView {
  constructor({ renderer, canvas, stage, toggles, controlsBar, parts, bounds }) {
    this.renderer = renderer;
    this.canvas = canvas;
    this.ctx2d = canvas.getContext('2d');
    this.bounds = bounds;
    this.scene = new Scene();
    this.scene.background = new Color(BACKGROUND);
    for (const part of Object.values(parts)) if (part) this.scene.add(part.object);
    const axes = new AxesHelper(bounds.radius * 0.15);
    this.scene.add(axes);

    this.camera = new PerspectiveCamera(50, 1, bounds.radius / 500, bounds.radius * 50);
    this.controls = null;
    this.up = '-y';
    this.pending = false;

    // Layer toggles.
    const layers = [['points', 'Points'], ['lines', 'Lines'], ['planes', 'Planes'], ['keyframes', 'Keyframes']];
    for (const [key, label] of layers) {
      const part = parts[key];
      const box = h('input', {
        type: 'checkbox', checked: Boolean(part), disabled: !part, dataset: { layer: key },
        onchange: (e) => {
          part.object.visible = e.target.checked;
          this.requestRender();
        },
      });
      toggles.append(h('label', { class: `control${part ? '' : ' disabled'}` }, box, ` ${label}`));
    }
    if (parts.points) {
      toggles.append(h('label', { class: 'control' }, 'Point size ',
        h('input', {
          type: 'range', min: '1', max: '6', step: '0.5', value: '2', 'aria-label': 'Point size',
          oninput: (e) => {
            parts.points.object.material.size = Number(e.target.value);
            this.requestRender();
          },
        })));
    }
    const upSelect = h('select', { 'aria-label': 'Up axis', onchange: (e) => { this.up = e.target.value; this.fit(); } },
      Object.entries(UP_CHOICES).map(([value, c]) => h('option', { value }, c.label)));
    controlsBar.append(
      h('label', { class: 'control' }, 'Up ', upSelect),
      h('button', { type: 'button', class: 'button', onclick: () => this.fit() }, 'Reset view'));

    this.resize();
    this.fit();
    new ResizeObserver(() => {
      if (this.resize()) this.render();
    }).observe(stage);
  }

  // Matches the canvas to its box; returns whether the size changed.
  resize() {
    const dpr = Math.min(window.devicePixelRatio || 1, 2);
    const w = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    const hgt = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    if (w === this.canvas.width && hgt === this.canvas.height) return false;
    this.canvas.width = w;
    this.canvas.height = hgt;
    this.camera.aspect = w / hgt;
    this.camera.updateProjectionMatrix();
    return true;
  }

  // Points the camera at the whole map from above and behind the start.
  fit() {
    const choice = UP_CHOICES[this.up];
    const { center, radius } = this.bounds;
    const vfov = (this.camera.fov * Math.PI) / 180;
    const hfov = 2 * Math.atan(Math.tan(vfov / 2) * this.camera.aspect);
    const distance = (radius / Math.sin(Math.min(vfov, hfov) / 2)) * 0.8;
    const from = new Vector3(...choice.from).normalize();
    this.camera.up.set(...choice.up);
    this.camera.position.copy(center).addScaledVector(from, distance);
    this.camera.near = distance / 1000;
    this.camera.far = distance * 20;
    this.camera.updateProjectionMatrix();
    // OrbitControls takes the up axis when it is created, so a new up needs new controls.
    if (this.controls) this.controls.dispose();
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.addEventListener('change', () => this.requestRender());
    this.controls.maxDistance = distance * 8;
    this.controls.minDistance = distance / 200;
    this.controls.target.copy(center);
    this.controls.update();
    this.render();
  }

  requestRender() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.render();
    });
  }

  render() {
    const { renderer, canvas } = this;
    const size = renderer.getDrawingBufferSize(new Vector2());
    if (size.x !== canvas.width || size.y !== canvas.height) {
      renderer.setPixelRatio(1);
      renderer.setSize(canvas.width, canvas.height, false);
    }
    renderer.render(this.scene, this.camera);
    this.ctx2d.drawImage(renderer.domElement, 0, 0);
    this.rendered = true;
  }
}
