// The live 3D map: the shared scene parts (web/shared/map-scene.js) rebuilt from each snapshot,
// the camera's trajectory, the ground truth, and the camera's frustum at its newest pose; the
// occupancy map's grid and voxels and the moving objects' boxes (occupancy-layers.js) as layers
// that can be hidden. Orbit, pan and zoom with the mouse; "follow" moves the view along with the
// camera.
import {
  WebGLRenderer, Scene, PerspectiveCamera, Color, BufferGeometry, Float32BufferAttribute,
  Line, LineBasicMaterial, LineSegments, AxesHelper, Vector3, Matrix4, LinearSRGBColorSpace,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import {
  BACKGROUND, UP_CHOICES, pointCloud, lineSegments, planes, keyframePath, sceneBounds,
} from '../../shared/map-scene.js';
import { gridMesh, voxelPoints, boxWireframes } from './occupancy-layers.js';

// The layers that can be switched off, each one three.js object (or none yet).
export const LAYERS = ['grid', 'voxels', 'people'];

const TRAJECTORY_COLOR = '#ff7f0e';
const GROUND_TRUTH_COLOR = '#9aa5b1';
const CAMERA_COLOR = '#0a7d2c';

// The camera's frustum in its own frame (x right, y down, z forward), 4:3, 0.12 m deep.
function frustumGeometry() {
  const d = 0.12;
  const x = 0.08;
  const y = 0.06;
  const c = [[-x, -y, d], [x, -y, d], [x, y, d], [-x, y, d]];
  const pos = [];
  for (const p of c) pos.push(0, 0, 0, ...p);
  for (let i = 0; i < 4; i++) pos.push(...c[i], ...c[(i + 1) % 4]);
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new Float32BufferAttribute(pos, 3));
  return geometry;
}

function disposeObject(object) {
  object.traverse((o) => {
    if (o.geometry) o.geometry.dispose();
    if (o.material) {
      if (o.material.map) o.material.map.dispose();
      o.material.dispose();
    }
  });
}

export class LiveMap {
  constructor(canvas, stage) {
    this.canvas = canvas;
    this.renderer = new WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.outputColorSpace = LinearSRGBColorSpace;
    this.scene = new Scene();
    this.scene.background = new Color(BACKGROUND);
    this.scene.add(new AxesHelper(0.2));
    this.camera = new PerspectiveCamera(50, 1, 0.01, 500);
    const choice = UP_CHOICES['-y'];
    this.camera.up.set(...choice.up);
    this.camera.position.set(...choice.from).multiplyScalar(3);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.requestRender());
    this.parts = [];
    this.namedParts = null;  // the newest snapshot's parts by name (points, lines, ...)
    this.fittedTo = null;  // the bounds of the newest fit ({center, radius}); null: not framed yet
    this.follow = true;
    this.lastCameraPosition = null;

    this.trajectory = new Line(new BufferGeometry(), new LineBasicMaterial({ color: TRAJECTORY_COLOR }));
    this.groundTruth = new Line(new BufferGeometry(), new LineBasicMaterial({ color: GROUND_TRUTH_COLOR }));
    this.frustum = new LineSegments(frustumGeometry(), new LineBasicMaterial({ color: CAMERA_COLOR }));
    this.frustum.matrixAutoUpdate = false;
    this.frustum.visible = false;
    this.scene.add(this.trajectory, this.groundTruth, this.frustum);
    this.layers = {};
    for (const name of LAYERS) this.layers[name] = { object: null, visible: true, count: 0 };
    this.rendered = false;
    this.resize();
    new ResizeObserver(() => {
      if (this.resize()) this.requestRender();
    }).observe(stage);
    this.requestRender();
  }

  setFollow(on) {
    this.follow = on;
  }

  setGroundTruth(flat) {
    this.groundTruth.geometry.dispose();
    const geometry = new BufferGeometry();
    geometry.setAttribute('position', new Float32BufferAttribute(flat, 3));
    this.groundTruth.geometry = geometry;
    this.requestRender();
  }

  setMap(snapshot) {
    for (const part of this.parts) {
      this.scene.remove(part.object);
      disposeObject(part.object);
    }
    const parts = {
      points: pointCloud(snapshot),
      lines: lineSegments(snapshot),
      planes: planes(snapshot),
      keyframes: keyframePath(snapshot),
    };
    this.namedParts = parts;
    this.parts = Object.values(parts).filter(Boolean);
    for (const part of this.parts) this.scene.add(part.object);
    this.trajectory.geometry.dispose();
    const geometry = new BufferGeometry();
    geometry.setAttribute('position', new Float32BufferAttribute(snapshot.trajectory, 3));
    this.trajectory.geometry = geometry;
    if (!this.fittedTo) this.fitToMap();
    this.requestRender();
  }

  // Frames the whole map as it is now (the first snapshot does it; the "Fit view" button again,
  // after the user has moved the view away or the map has grown beyond it).
  fitToMap() {
    const bounds = this.namedParts ? sceneBounds(this.namedParts) : null;
    if (!bounds) return;
    this.fit(bounds);
    this.fittedTo = { center: bounds.center.toArray(), radius: bounds.radius };
    this.requestRender();
  }

  // Replaces a layer's object (null: nothing to draw); its visibility stays as switched.
  replaceLayer(name, object, count) {
    const layer = this.layers[name];
    if (layer.object) {
      this.scene.remove(layer.object);
      disposeObject(layer.object);
    }
    layer.object = object;
    layer.count = object ? count : 0;
    if (object) {
      object.visible = layer.visible;
      this.scene.add(object);
    }
    this.requestRender();
  }

  // occupancy: the decoded occupancy message ({grid, voxels}, see main.js).
  setOccupancy(occupancy) {
    const { grid, voxels } = occupancy;
    this.replaceLayer('grid', gridMesh(grid), grid.width * grid.height);
    this.replaceLayer('voxels', voxelPoints(voxels, this.camera.fov), voxels.count);
  }

  // boxes: the newest frame's moving objects ({min, max, state} in the world frame).
  setObjectBoxes(boxes) {
    const count = Array.isArray(boxes) ? boxes.length : 0;
    if (!count && !this.layers.people.object) return;
    this.replaceLayer('people', boxWireframes(boxes), count);
  }

  setLayerVisible(name, visible) {
    const layer = this.layers[name];
    layer.visible = visible;
    if (layer.object) layer.object.visible = visible;
    this.requestRender();
  }

  // What each layer draws now (for the page's state, read by the browser test).
  layerState() {
    const out = {};
    for (const name of LAYERS) {
      const { object, visible, count } = this.layers[name];
      out[name] = { visible, drawn: Boolean(object && object.visible && object.parent === this.scene), count };
    }
    return out;
  }

  // Where the view looks from and at, and what it was fitted to (for the page's state).
  viewState() {
    const round = (a) => a.map((x) => Number(x.toFixed(3)));
    return {
      from: round(this.camera.position.toArray()),
      at: round(this.controls.target.toArray()),
      fittedTo: this.fittedTo && { center: round(this.fittedTo.center), radius: Number(this.fittedTo.radius.toFixed(3)) },
      canvas: [this.canvas.width, this.canvas.height],
    };
  }

  // pose: the camera's T_w_c as 16 numbers, column-major (or null when not tracked).
  setPose(pose) {
    if (!Array.isArray(pose) || pose.length !== 16) return;
    const matrix = new Matrix4().fromArray(pose);
    this.frustum.matrix.copy(matrix);
    this.frustum.matrixWorldNeedsUpdate = true;
    this.frustum.visible = true;
    const position = new Vector3().setFromMatrixPosition(matrix);
    if (this.follow && this.lastCameraPosition) {
      const delta = position.clone().sub(this.lastCameraPosition);
      this.camera.position.add(delta);
      this.controls.target.add(delta);
      this.controls.update();
    }
    this.lastCameraPosition = position;
    this.requestRender();
  }

  fit({ center, radius }) {
    const choice = UP_CHOICES['-y'];
    const distance = Math.max(1.5, radius * 2.2);
    this.camera.position.copy(center).addScaledVector(new Vector3(...choice.from).normalize(), distance);
    this.camera.near = distance / 1000;
    this.camera.far = distance * 50;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
  }

  resize() {
    const dpr = Math.min(window.devicePixelRatio || 1, 2);
    const w = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    const hgt = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    if (w === this.canvas.width && hgt === this.canvas.height) return false;
    this.renderer.setPixelRatio(1);
    this.renderer.setSize(w, hgt, false);
    this.camera.aspect = w / hgt;
    this.camera.updateProjectionMatrix();
    return true;
  }

  requestRender() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      const start = performance.now();
      this.renderer.render(this.scene, this.camera);
      this.renderMs = performance.now() - start;
      this.rendered = true;
    });
  }
}
