// Header, summary cards, ablation table, per-run details, published figures,
// failed runs and the raw Markdown.
import { h, note } from '../../shared/dom.js';
import { isNum, num, withUnit, range, duration, dateTime, text, DASH } from '../../shared/format.js';

// The ablation table's metric columns. "better" tells which end is highlighted.
const METRICS = [
  { key: 'ate_rmse_m', title: 'ATE seq.', sub: 'RMSE, m', unit: 'm', better: 'low' },
  { key: 'ate_rmse_threaded_m', title: 'ATE threaded', sub: 'RMSE, m', unit: 'm', better: 'low' },
  { key: 'rpe_trans_m', title: 'RPE trans.', sub: 'RMSE at 1 s, m', unit: 'm', better: 'low' },
  { key: 'rpe_rot_deg', title: 'RPE rot.', sub: 'RMSE at 1 s, °', unit: 'deg', better: 'low' },
  { key: 'tracked_ratio', title: 'Tracked', sub: '% of frames', unit: 'ratio', better: 'high' },
  { key: 'fps', title: 'FPS', sub: 'threaded', unit: 'fps', better: 'high' },
  { key: 'tracking_ms', title: 'Tracking', sub: 'ms/frame, threaded', unit: 'ms', better: 'low' },
  // Real-time runs (bench --modes ...,realtime): shown only when some result has them.
  { key: 'ate_rmse_realtime_m', title: 'ATE real time', sub: 'RMSE, m, frames processed', unit: 'm', better: 'low', optional: true },
  { key: 'realtime_processed_ratio', title: 'Processed', sub: '% of frames, real time', unit: 'ratio', better: 'high', optional: true },
  { key: 'realtime_latency_ms', title: 'Latency', sub: 'ms, frame to pose, real time', unit: 'ms', better: 'low', optional: true },
];

function median(stat) {
  return stat && isNum(stat.median) ? stat.median : null;
}

// Configs whose result is best in a column, compared at display precision so that
// ties on screen are highlighted together. Needs at least two values to compare.
function bestConfigs(results, metric) {
  const values = [];
  for (const res of results) {
    if (res.skipped) continue;
    const m = median(res[metric.key]);
    if (m !== null) values.push([res.config, Number(num(m, metric.unit))]);
  }
  if (values.length < 2) return new Set();
  const pick = metric.better === 'high' ? Math.max : Math.min;
  const best = pick(...values.map((v) => v[1]));
  return new Set(values.filter((v) => v[1] === best).map((v) => v[0]));
}

function swatch(color) {
  return h('span', { class: 'swatch', style: { background: color }, 'aria-hidden': 'true' });
}

function configCell(ctx, name) {
  const cfg = ctx.config(name);
  return h('span', { class: 'config-name', title: cfg.description || null },
    swatch(ctx.color(name)), cfg.label || name);
}

function runCounts(res) {
  const runs = Array.isArray(res.runs) ? res.runs : [];
  return { total: runs.length, failed: runs.filter((r) => r && r.ok === false).length };
}

// ---------------------------------------------------------------- header

export function header(data, ctx) {
  const machine = data.machine || {};
  const modes = Array.isArray(data.modes) ? data.modes : [];
  let total = 0;
  let failed = 0;
  for (const seq of data.sequences || []) {
    for (const res of seq.results || []) {
      const c = runCounts(res);
      total += c.total;
      failed += c.failed;
    }
  }
  const machineText = [machine.hostname, isNum(machine.cpus) ? `${machine.cpus} CPU${machine.cpus === 1 ? '' : 's'}` : null]
    .filter(Boolean).join(' · ') || DASH;
  const runsText = isNum(data.runs_per_mode)
    ? `${data.runs_per_mode} per mode${modes.length ? ` (${modes.join(', ')})` : ''}`
    : DASH;

  const meta = h('dl', { class: 'meta' },
    h('dt', null, 'Created'), h('dd', null, dateTime(data.created_utc)),
    h('dt', null, 'Command'), h('dd', null, h('code', null, text(data.command))),
    h('dt', null, 'Machine'), h('dd', null, machineText),
    h('dt', null, 'Runs'), h('dd', null, runsText),
    h('dt', null, 'Wall time'), h('dd', null, duration(data.wall_time_s)),
    data.executor ? h('dt', null, 'Executed by') : null,
    data.executor ? h('dd', null, text(data.executor)) : null,
  );
  const cards = h('div', { class: 'cards' },
    card('Sequences', String((data.sequences || []).length)),
    card('Configs', String(ctx.configs.length), ctx.configs.map((c) => c.label || c.name).join(', ')),
    card('Runs ok', `${total - failed} / ${total}`, failed ? `${failed} failed` : 'none failed', failed ? 'bad' : 'good'),
    card('Bench wall time', duration(data.wall_time_s)),
  );
  return h('header', { class: 'page-header' },
    h('h1', null, 'mcslam bench report'),
    h('p', { class: 'lead' }, 'Accuracy comes from the sequential runs, speed from the threaded runs; each figure is the median over the runs, with min–max below it.'),
    meta, cards);
}

function card(title, value, detail, tone) {
  return h('div', { class: `card${tone ? ` card-${tone}` : ''}` },
    h('div', { class: 'card-title' }, title),
    h('div', { class: 'card-value' }, value),
    detail ? h('div', { class: 'card-detail' }, detail) : null);
}

// Summary cards of one sequence: best ATE and how the full config does.
export function sequenceCards(seq, ctx) {
  const results = (seq.results || []).filter((r) => r && !r.skipped);
  const byName = new Map(results.map((r) => [r.config, r]));
  let best = null;
  for (const res of results) {
    const m = median(res.ate_rmse_m);
    if (m !== null && (best === null || m < best.value)) best = { value: m, config: res.config };
  }
  const full = byName.get(ctx.fullConfig);
  const fullLabel = ctx.config(ctx.fullConfig).label || ctx.fullConfig;
  return h('div', { class: 'cards' },
    card('Best ATE (seq.)', best ? withUnit(best.value, 'm') : DASH,
      best ? ctx.config(best.config).label || best.config : 'no ground truth or no successful run'),
    card(`ATE · ${ctx.fullConfig}`, withUnit(median(full && full.ate_rmse_m), 'm'),
      full && full.ate_rmse_m ? `${range(full.ate_rmse_m, 'm') || 'one run'}` : fullLabel),
    card(`FPS · ${ctx.fullConfig}`, withUnit(median(full && full.fps), 'fps'),
      full && median(full.tracking_ms) !== null ? `${withUnit(median(full.tracking_ms), 'ms')} per frame` : fullLabel),
    card(`Tracked · ${ctx.fullConfig}`, withUnit(median(full && full.tracked_ratio), 'ratio'), fullLabel),
  );
}

export function sequenceMeta(seq) {
  return h('dl', { class: 'meta meta-small' },
    h('dt', null, 'Dataset'), h('dd', null, text(seq.dataset)),
    h('dt', null, 'Frames'), h('dd', null, isNum(seq.frames) ? String(seq.frames) : DASH),
    h('dt', null, 'Ground truth'), h('dd', null, seq.groundtruth ? `yes (${(seq.groundtruth.t || []).length} poses)` : 'none: no ATE/RPE'),
    h('dt', null, 'Object boxes'), h('dd', null, seq.boxes ? String(seq.boxes) : 'none'),
  );
}

// ---------------------------------------------------------------- overview

// Sequences × configs matrix of the sequential ATE median (only with several sequences).
export function overview(data, ctx) {
  const metric = METRICS[0];
  const head = h('tr', null, h('th', { scope: 'col' }, 'Sequence'),
    ctx.configs.map((c) => h('th', { scope: 'col' }, configCell(ctx, c.name))));
  const rows = (data.sequences || []).map((seq, i) => {
    const results = seq.results || [];
    const best = bestConfigs(results, metric);
    return h('tr', null,
      h('th', { scope: 'row' }, h('a', { href: `#${ctx.sequenceId(i)}` }, text(seq.name))),
      ctx.configs.map((c) => {
        const res = results.find((r) => r && r.config === c.name);
        if (!res) return h('td', { class: 'num muted' }, DASH);
        if (res.skipped) return h('td', { class: 'num muted', title: res.skipped }, 'skipped');
        return h('td', { class: `num${best.has(c.name) ? ' best' : ''}` }, num(median(res.ate_rmse_m), 'm'));
      }));
  });
  return h('div', { class: 'table-wrap' },
    h('table', { class: 'data overview' },
      h('caption', null, 'ATE RMSE of the sequential runs (m, median); best per sequence in bold'),
      h('thead', null, head), h('tbody', null, rows)));
}

// ---------------------------------------------------------------- ablation

export function ablationTable(seq, ctx) {
  const results = (seq.results || []).filter(Boolean);
  const shown = METRICS.filter((m) => !m.optional || results.some((r) => median(r[m.key]) !== null));
  const best = new Map(shown.map((m) => [m.key, bestConfigs(results, m)]));
  const head = h('tr', null,
    h('th', { scope: 'col' }, 'Config'),
    shown.map((m) => h('th', { scope: 'col', class: 'num' }, m.title, h('span', { class: 'sub' }, m.sub))));
  const rows = results.map((res) => {
    const counts = runCounts(res);
    const nameCell = h('th', { scope: 'row' }, configCell(ctx, res.config),
      counts.failed ? h('span', { class: 'badge badge-bad', title: 'failed runs, see the run details' },
        `${counts.failed} failed`) : null);
    if (res.skipped) {
      return h('tr', { class: 'skipped', dataset: { config: res.config } }, nameCell,
        h('td', { colspan: shown.length }, h('span', { class: 'badge' }, 'skipped'), ' ', String(res.skipped)));
    }
    return h('tr', { dataset: { config: res.config } }, nameCell, shown.map((m) => {
      const stat = res[m.key];
      const r = range(stat, m.unit);
      const isBest = best.get(m.key).has(res.config);
      return h('td', { class: `num${isBest ? ' best' : ''}`, title: stat && isNum(stat.n) ? `${stat.n} run${stat.n === 1 ? '' : 's'}` : null },
        num(median(stat), m.unit), r ? h('span', { class: 'sub' }, r) : null);
    }));
  });
  return h('div', { class: 'table-wrap' },
    h('table', { class: 'data ablation' },
      h('caption', null, 'Median over the runs, min–max below; the best value of each column is highlighted'),
      h('thead', null, head), h('tbody', null, rows)));
}

const RUN_COLUMNS = [
  ['ATE', 'ate_rmse_m', 'm'], ['RPE t', 'rpe_trans_m', 'm'], ['RPE r', 'rpe_rot_deg', 'deg'],
  ['Tracked %', 'tracked_ratio', 'ratio'], ['FPS', 'fps', 'fps'], ['Track ms', 'tracking_ms', 'ms'], ['Wall s', 'wall_s', 's'],
];

export function runDetails(seq, ctx) {
  const rows = [];
  let total = 0;
  let failed = 0;
  for (const res of seq.results || []) {
    if (!res) continue;
    for (const run of res.runs || []) {
      if (!run) continue;
      total += 1;
      const ok = run.ok !== false;
      if (!ok) failed += 1;
      rows.push(h('tr', { class: ok ? null : 'failed' },
        h('td', null, configCell(ctx, res.config)),
        h('td', null, text(run.mode)),
        h('td', { class: 'num' }, text(run.index)),
        h('td', null, h('span', { class: `badge ${ok ? 'badge-good' : 'badge-bad'}` }, ok ? 'ok' : 'failed')),
        RUN_COLUMNS.map(([, key, unit]) => h('td', { class: 'num' }, num(run[key], unit))),
        h('td', null, run.output ? h('code', null, String(run.output)) : DASH)));
      if (!ok) {
        rows.push(h('tr', { class: 'failed error-row' },
          h('td', { colspan: 5 + RUN_COLUMNS.length }, h('pre', { class: 'error' }, text(run.error)))));
      }
    }
  }
  if (!total) return note('No runs recorded for this sequence.');
  const head = h('tr', null, ['Config', 'Mode', '#', 'Status'].map((t) => h('th', { scope: 'col' }, t)),
    RUN_COLUMNS.map(([t]) => h('th', { scope: 'col', class: 'num' }, t)), h('th', { scope: 'col' }, 'Output'));
  return h('details', { class: 'runs' },
    h('summary', null, `Every run (${total}${failed ? `, ${failed} failed` : ''})`),
    h('div', { class: 'table-wrap' },
      h('table', { class: 'data runs-table' }, h('thead', null, head), h('tbody', null, rows))));
}

// ---------------------------------------------------------------- published

function generic(x) {
  if (!isNum(x)) return DASH;
  const a = Math.abs(x);
  return x.toFixed(a < 1 ? 4 : a < 100 ? 2 : 1);
}

export function publishedTables(seq, ctx) {
  const entries = (seq.published || []).filter(Boolean);
  return h('div', { class: 'published' }, entries.map((entry) => {
    const higherBetter = /fps|hz|tracked|success|recall|precision/i.test(String(entry.metric || ''));
    const values = (Array.isArray(entry.values) ? entry.values : [])
      .filter((v) => Array.isArray(v))
      .map(([method, value]) => ({ method: text(method), value, ours: false }));
    const oursName = entry.ours_config ? ctx.config(entry.ours_config).label || entry.ours_config : 'ours';
    values.push({ method: `mcslam, ${oursName}`, value: entry.ours, ours: true });
    // The ATE of the poses given at the time, beside that of the unsmoothed final poses.
    if (isNum(entry.ours_online)) values.push({ method: `mcslam online, ${oursName}`, value: entry.ours_online, ours: true });
    const numeric = values.filter((v) => isNum(v.value)).map((v) => v.value);
    const max = numeric.length ? Math.max(...numeric.map(Math.abs)) : 0;
    const best = numeric.length > 1 ? (higherBetter ? Math.max : Math.min)(...numeric) : null;
    const rows = values.map((v) => {
      const pct = isNum(v.value) && max > 0 ? Math.max(1, (Math.abs(v.value) / max) * 100) : 0;
      return h('tr', { class: v.ours ? 'ours' : null },
        h('th', { scope: 'row' }, v.method),
        h('td', { class: `num${v.value === best ? ' best' : ''}` }, isNum(v.value) ? generic(v.value) : (v.ours ? 'not measured' : DASH)),
        h('td', { class: 'bar-cell', 'aria-hidden': 'true' }, h('span', { class: 'bar', style: { width: `${pct}%` } })));
    });
    return h('figure', { class: 'published-entry' },
      h('h4', null, [entry.table, entry.metric].filter(Boolean).join(' · ') || 'Published figure'),
      h('table', { class: 'data compact' },
        h('thead', null, h('tr', null, h('th', { scope: 'col' }, 'Method'), h('th', { scope: 'col', class: 'num' }, 'Value'), h('th', null, ''))),
        h('tbody', null, rows)),
      h('figcaption', null, 'Source: ', text(entry.source)));
  }));
}

// ---------------------------------------------------------------- failed runs, markdown

export function failedRuns(data) {
  const failed = Array.isArray(data.failed_runs) ? data.failed_runs.filter(Boolean) : [];
  if (!failed.length) return note('No run failed.', 'good');
  return h('div', { class: 'table-wrap failed-wrap' },
    h('table', { class: 'data failed-runs' },
      h('thead', null, h('tr', null, ['Sequence', 'Config', 'Mode', '#', 'Error'].map((t) => h('th', { scope: 'col' }, t)))),
      h('tbody', null, failed.map((f) => h('tr', null,
        h('td', null, text(f.sequence)), h('td', null, text(f.config)), h('td', null, text(f.mode)),
        h('td', { class: 'num' }, text(f.index)), h('td', null, h('pre', { class: 'error' }, text(f.error))))))));
}

export function markdown(data) {
  const md = typeof data.markdown === 'string' ? data.markdown : '';
  if (!md.trim()) return note('No Markdown was recorded.');
  return h('details', { class: 'markdown' },
    h('summary', null, 'Raw Markdown (the same tables as results.md)'),
    h('pre', null, md));
}
