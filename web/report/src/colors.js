// Colours: one per config (same in every chart and sequence), one per pipeline stage.

const CONFIG_PALETTE = [
  '#4e79a7', '#f28e2b', '#59a14f', '#e15759', '#b07aa1',
  '#76b7b2', '#edc948', '#ff9da7', '#9c755f', '#17becf',
];

const STAGE_PALETTE = [
  '#80b1d3', '#fdb462', '#b3de69', '#fb8072', '#bebada',
  '#8dd3c7', '#fccde5', '#bc80bd', '#ccebc5', '#ffed6f', '#d9d9d9', '#a6761d',
];

export const GROUND_TRUTH_COLOR = '#222222';

// The ablation configs of mcslam bench keep their colour whichever of them ran;
// other names take the remaining colours in order.
const KNOWN_CONFIGS = ['points', 'lines', 'planes', 'detection', 'full'];

export function makeConfigColors(configs) {
  const map = new Map();
  let next = KNOWN_CONFIGS.length;
  for (const c of configs) {
    const known = KNOWN_CONFIGS.indexOf(c.name);
    map.set(c.name, CONFIG_PALETTE[(known >= 0 ? known : next++) % CONFIG_PALETTE.length]);
  }
  return (name) => map.get(name) || '#888888';
}

// Stage colours are assigned in first-seen order over all sequences and configs, so a
// stage keeps its colour across every timing chart of the report.
export function makeStageColors(sequences) {
  const map = new Map();
  for (const seq of sequences || []) {
    for (const res of seq.results || []) {
      for (const entry of res.stages_ms || []) {
        const name = Array.isArray(entry) ? String(entry[0]) : null;
        if (name !== null && !map.has(name)) map.set(name, STAGE_PALETTE[map.size % STAGE_PALETTE.length]);
      }
    }
  }
  return (name) => map.get(name) || '#999999';
}
