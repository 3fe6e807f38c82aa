// The 3D map's scene, shared by the bench report (web/report) and the live viewer (web/viewer):
// three.js objects for points, line segments, planes and the keyframe path made from plain or
// typed arrays, the bounds that frame them, and the choices of "up".
import {
  BufferGeometry, Float32BufferAttribute, BufferAttribute, Points, PointsMaterial, LineSegments,
  LineBasicMaterial, Line, LineLoop, Mesh, MeshBasicMaterial, DoubleSide, Color, Vector3, Group,
  ColorManagement,
} from 'three';
import { isNum } from './format.js';

// Colours in the data are shown as they are (no sRGB/linear conversion).
ColorManagement.enabled = false;

export const BACKGROUND = '#f3f5f8';
export const POINT_COLOR = '#56657a';
export const LINE_COLOR = '#d62728';
export const KEYFRAME_COLOR = '#7b2cbf';
export const PLANE_COLORS = ['#1f77b4', '#2ca02c', '#ff7f0e', '#17becf', '#bcbd22', '#e377c2', '#8c564b', '#9467bd'];

// The direction the camera looks from, for each choice of "up". The map frame is
// usually the first camera's frame (x right, y down, z forward), hence "-y" by default.
export const UP_CHOICES = {
  '-y': { label: '−y (camera frame)', up: [0, -1, 0], from: [0.35, -0.75, -1] },
  '+z': { label: '+z', up: [0, 0, 1], from: [0.35, -1, 0.75] },
  '+y': { label: '+y', up: [0, 1, 0], from: [0.35, 0.75, 1] },
  '-z': { label: '−z', up: [0, 0, -1], from: [0.35, -1, -0.75] },
};

// A plain array or a typed array (the live viewer's binary map).
function isList(v) {
  return Array.isArray(v) || ArrayBuffer.isView(v);
}

// ---------------------------------------------------------------- geometry from data

function flatTriples(values) {
  if (!isList(values)) return new Float32Array(0);
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

export function pointCloud(map) {
  const raw = isList(map.points) ? map.points : [];
  const n = Math.floor(raw.length / 3);
  const colors = isList(map.colors) && map.colors.length >= n * 3 ? map.colors : null;
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

export function lineSegments(map) {
  const flat = isList(map.lines) ? map.lines : [];
  const pos = [];
  for (let i = 0; i + 5 < flat.length; i += 6) {
    const seg = Array.from(flat.slice(i, i + 6));
    if (seg.every(isNum)) pos.push(...seg);
  }
  if (!pos.length) return null;
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new Float32BufferAttribute(pos, 3));
  return { object: new LineSegments(geometry, new LineBasicMaterial({ color: LINE_COLOR })), count: pos.length / 6, positions: pos };
}

export function planes(map) {
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

export function keyframePath(map) {
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
// (stray landmarks), plus the planes' corners and the keyframes that lie within that box grown
// by its own size on each side (all of them when there are no points or lines): a keyframe or a
// plane corner further out is a stray too (a pose lost and found elsewhere), and framing it
// would shrink the map to a speck.
export function sceneBounds(parts) {
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
  const core = Number.isFinite(min[0]) ? { min: [...min], max: [...max] } : null;
  const size = core ? Math.max(...[0, 1, 2].map((a) => core.max[a] - core.min[a])) : 0;
  const near = (pos, i) => !core || [0, 1, 2].every((a) =>
    pos[i + a] >= core.min[a] - size && pos[i + a] <= core.max[a] + size);
  for (const key of ['planes', 'keyframes']) {
    const pos = parts[key] && parts[key].positions;
    if (!pos) continue;
    for (let i = 0; i + 2 < pos.length; i += 3) {
      if (!near(pos, i)) continue;
      for (let axis = 0; axis < 3; axis++) include(pos[i + axis], axis);
    }
  }
  if (!Number.isFinite(min[0])) return null;
  const center = new Vector3((min[0] + max[0]) / 2, (min[1] + max[1]) / 2, (min[2] + max[2]) / 2);
  const radius = Math.max(0.05, 0.5 * Math.hypot(max[0] - min[0], max[1] - min[1], max[2] - min[2]));
  return { center, radius };
}
