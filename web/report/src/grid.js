// The occupancy grid of a sequence's run (grid.png, as map_server reads it) with its figures.
import { h, note } from '../../shared/dom.js';
import { isNum, withUnit } from '../../shared/format.js';

function figures(occ) {
  if (!occ || typeof occ !== 'object') return [];
  const out = [];
  const cells = occ.grid && occ.grid.cells;
  if (cells && isNum(cells.occupied)) {
    out.push(`cells: ${cells.occupied} occupied, ${cells.free} free, ${cells.unknown} unknown`);
  }
  if (isNum(occ.resolution)) out.push(`resolution ${withUnit(occ.resolution, 'm')}`);
  if (isNum(occ.keyframes)) out.push(`${occ.keyframes} keyframes`);
  const t = occ.time_per_keyframe_ms;
  if (t && isNum(t.median)) out.push(`mapping ${withUnit(t.median, 'ms')} per keyframe (p95 ${withUnit(t.p95, 'ms')})`);
  const q = occ.quality;
  if (q && isNum(q.ghost_rate)) {
    out.push(`ghost rate ${withUnit(q.ghost_rate, 'ratio')}, completeness ${withUnit(q.completeness, 'ratio')} (against the synthetic scene)`);
  }
  return out;
}

// Returns {element, mount}; mount() resolves when the picture has decoded (or failed).
export function gridPart(seq, seqIndex) {
  const grid = seq.grid;
  if (!grid || typeof grid.png_base64 !== 'string' || !grid.png_base64.length) {
    return { element: note('No occupancy grid for this sequence (mapping off, or no run finished).'), mount: null };
  }
  const caption = `Occupancy grid of ${grid.config ? `configuration ${grid.config}` : 'the run'}${grid.run ? ` (${grid.run})` : ''}: black occupied, white free, grey unknown; people left out.`;
  const img = h('img', { src: `data:image/png;base64,${grid.png_base64.replace(/\s+/g, '')}`, alt: caption, class: 'grid-image', dataset: { grid: String(seqIndex) } });
  const fig = h('figure', { class: 'grid' }, img, h('figcaption', null, caption,
    h('ul', { class: 'grid-figures' }, figures(grid.occupancy).map((f) => h('li', null, f)))));
  const mount = () => [img.decode().catch((err) => {
    console.warn('mcslam report: could not decode the occupancy grid:', err);
    fig.replaceWith(note('Could not show the occupancy grid.', 'error'));
  })];
  return { element: fig, mount };
}
