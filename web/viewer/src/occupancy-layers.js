// The live map's layers from the dense occupancy map and the tracked frame's moving objects:
// the 2D grid on the floor plane, the occupied voxels as squares in their colours, and the
// people's (and constrained movers') boxes as wireframes. Each function returns a three.js object
// (or null when there is nothing to draw); LiveMap adds, toggles and disposes them.
import {
  BufferGeometry, BufferAttribute, Float32BufferAttribute, PlaneGeometry, DataTexture, RGBAFormat,
  UnsignedByteType, NearestFilter, LinearFilter, Mesh, MeshBasicMaterial, Points, PointsMaterial,
  Group, LineSegments, LineBasicMaterial, DoubleSide, Color,
} from 'three';

// RGBA of a cell: occupied dark, free light, unknown transparent.
export const GRID_OCCUPIED = [38, 48, 64, 235];
export const GRID_FREE = [190, 215, 238, 190];
export const DYNAMIC_BOX_COLOR = '#e60000';
export const CONSTRAINED_BOX_COLOR = '#f2c200';

// grid: {width, height, resolution, T (16 numbers, column-major T_world_grid), cells (int8,
// row-major, row 0 the lowest y: -1 unknown, 0 free, 100 occupied)}. A plane of width x height
// cells whose lower-left corner is above the grid frame's origin, placed in the world by T.
export function gridMesh(grid) {
  const { width, height, resolution, T, cells } = grid;
  if (!(width > 0 && height > 0 && cells.length >= width * height)) return null;
  const rgba = new Uint8Array(4 * width * height);
  for (let i = 0; i < width * height; i++) {
    const v = cells[i];
    if (v < 0) continue;  // unknown: transparent
    rgba.set(v >= 50 ? GRID_OCCUPIED : GRID_FREE, 4 * i);
  }
  // Texture row 0 is v = 0, the plane's lowest y: the grid's row 0.
  const texture = new DataTexture(rgba, width, height, RGBAFormat, UnsignedByteType);
  texture.magFilter = NearestFilter;
  texture.minFilter = LinearFilter;
  texture.generateMipmaps = false;
  texture.needsUpdate = true;
  const w = width * resolution;
  const hgt = height * resolution;
  const geometry = new PlaneGeometry(w, hgt);
  // A cell's size above the floor (the grid frame's z is the floor's normal): the floor's own
  // voxels (below the grid's height band) would hide it, the obstacles' rise through it.
  geometry.translate(w / 2, hgt / 2, resolution);
  const mesh = new Mesh(geometry, new MeshBasicMaterial({
    map: texture, transparent: true, side: DoubleSide, depthWrite: false,
  }));
  mesh.matrixAutoUpdate = false;
  mesh.matrix.fromArray(T);
  mesh.matrixWorldNeedsUpdate = true;
  mesh.renderOrder = 1;  // over the map's transparent planes
  return mesh;
}

// voxels: {count, centres (3 per voxel), sizes (edge, metres), rgb (3 uint8 per voxel)}, seen
// through a perspective camera of vertical field of view fovDeg. Squares facing the camera, as
// wide as the voxel where it is (a little more, so that neighbours close up): one vertex each,
// where a cube has 24 (in software rendering, 20,000 cubes took 0.6 s a frame, the squares a few
// ms). One Points object per voxel size (pruned nodes are larger).
export function voxelPoints({ count, centres, sizes, rgb }, fovDeg) {
  if (!(count > 0)) return null;
  const bySize = new Map();
  for (let i = 0; i < count; i++) {
    if (!bySize.has(sizes[i])) bySize.set(sizes[i], []);
    bySize.get(sizes[i]).push(i);
  }
  // three.js draws an attenuated point `size * (height / 2) / depth` pixels wide; the voxel
  // projects to `edge * (height / 2) / (depth * tan(fov / 2))`.
  const perEdge = 1.15 / Math.tan((fovDeg / 2) * (Math.PI / 180));
  const group = new Group();
  for (const [edge, list] of bySize) {
    const pos = new Float32Array(3 * list.length);
    const col = new Uint8Array(3 * list.length);
    list.forEach((i, j) => {
      pos.set(centres.subarray(3 * i, 3 * i + 3), 3 * j);
      col.set(rgb.subarray(3 * i, 3 * i + 3), 3 * j);
    });
    const geometry = new BufferGeometry();
    geometry.setAttribute('position', new BufferAttribute(pos, 3));
    geometry.setAttribute('color', new BufferAttribute(col, 3, true));
    group.add(new Points(geometry, new PointsMaterial({
      size: edge * perEdge, sizeAttenuation: true, vertexColors: true,
    })));
  }
  return group;
}

// boxes: [{min: [x, y, z], max: [x, y, z], state: "dynamic" | "constrained"}] in the world frame.
export function boxWireframes(boxes) {
  const valid = (boxes || []).filter((b) => Array.isArray(b.min) && Array.isArray(b.max)
    && b.min.length === 3 && b.max.length === 3 && [...b.min, ...b.max].every(Number.isFinite));
  if (!valid.length) return null;
  const pos = [];
  const col = [];
  for (const b of valid) {
    const color = new Color(b.state === 'constrained' ? CONSTRAINED_BOX_COLOR : DYNAMIC_BOX_COLOR);
    const corner = (i) => [0, 1, 2].map((a) => ((i >> a) & 1 ? b.max[a] : b.min[a]));
    // The 12 edges: corners that differ in one axis.
    for (let i = 0; i < 8; i++) {
      for (let a = 0; a < 3; a++) {
        if ((i >> a) & 1) continue;
        pos.push(...corner(i), ...corner(i | (1 << a)));
        col.push(color.r, color.g, color.b, color.r, color.g, color.b);
      }
    }
  }
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new Float32BufferAttribute(pos, 3));
  geometry.setAttribute('color', new Float32BufferAttribute(col, 3));
  const lines = new LineSegments(geometry, new LineBasicMaterial({ vertexColors: true }));
  lines.renderOrder = 2;
  return lines;
}
