// web/shared/map-scene.js's sceneBounds, which frames the 3D views (the live viewer's first
// snapshot and "Fit view", the bench report's map): stray landmarks and a keyframe or plane
// corner far from the map do not shrink the map to a speck; without points or lines the
// keyframes are framed in full. Bundled with esbuild and run by node (web_module_test.sh).
import { sceneBounds } from '../../web/shared/map-scene.js';

let failures = 0;
function check(ok, message) {
  console.log(`${ok ? 'ok  ' : 'FAIL'}  ${message}`);
  if (!ok) failures += 1;
}

// A room 4 x 3 x 4 m of points on a fixed grid (deterministic), with 5 stray landmarks 80 m out.
const points = [];
for (let x = 0; x < 20; x++) for (let y = 0; y < 15; y++) for (let z = 0; z < 20; z += 4) points.push(-2 + 0.2 * x, -1.5 + 0.2 * y, 0.2 * z);
for (let i = 0; i < 5; i++) points.push(80, 0, 80);
const keyframes = [0, 0, 0, 0.5, 0, 0.2, 1.0, 0.1, 0.4];
const room = sceneBounds({ points: { positions: points }, keyframes: { positions: keyframes } });
check(room.radius > 2 && room.radius < 4, `the room is framed (radius ${room.radius.toFixed(2)} m)`);

// One keyframe 300 m away (a pose lost and found elsewhere) and a plane corner 50 m away: framed
// as without them (the plane's two corners at the room's edge are framed).
const corners = [0, 1.5, 0, 2, 1.5, 0];
const plane = sceneBounds({ points: { positions: points }, keyframes: { positions: keyframes }, planes: { positions: corners } });
const stray = sceneBounds({
  points: { positions: points },
  keyframes: { positions: [...keyframes, 300, 10, 50] },
  planes: { positions: [...corners, 50, 1.5, 50] },
});
check(Math.abs(stray.radius - plane.radius) < 1e-9 && stray.center.distanceTo(plane.center) < 1e-9,
  `a stray keyframe and plane corner are left out (radius ${stray.radius.toFixed(2)} m, ${plane.radius.toFixed(2)} m without them)`);

// A keyframe just outside the points' box (the camera stands back from what it sees) is framed.
const back = sceneBounds({ points: { positions: points }, keyframes: { positions: [...keyframes, 0, 0, -3] } });
check(back.radius > room.radius + 0.5, `a keyframe near the map is framed (radius ${back.radius.toFixed(2)} m)`);

// Keyframes alone: all of them.
const alone = sceneBounds({ keyframes: { positions: [0, 0, 0, 300, 10, 50] } });
check(alone.radius > 150, `without points every keyframe is framed (radius ${alone.radius.toFixed(2)} m)`);

check(sceneBounds({}) === null, 'nothing to frame: null');
process.exit(failures ? 1 : 0);
