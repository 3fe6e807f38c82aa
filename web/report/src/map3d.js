// 3D map view (three.js): points, line segments, planes and the keyframe trajectory,
// with orbit controls.
//
// All map views share one WebGL renderer whose canvas is not in the page: a view
// renders into it and copies the picture onto its own 2D canvas. This keeps a single
// WebGL context however many sequences the report has (browsers allow only a few),
// and the visible canvas can always be read back.
import {
  WebGLRenderer, Scene, PerspectiveCamera, Color, Vector2, Vector3, AxesHelper, LinearSRGBColorSpace,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { h, note } from '../../shared/dom.js';
import {
  BACKGROUND, UP_CHOICES, pointCloud, lineSegments, planes, keyframePath, sceneBounds,
} from '../../shared/map-scene.js';

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
