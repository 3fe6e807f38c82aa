// 2D charts (Chart.js): trajectory top view and x/y/z over time, ATE error over time,
// per-stage timing bars. Only the Chart.js parts used here are registered.
import {
  Chart, ScatterController, BarController, LineElement, PointElement, BarElement,
  LinearScale, CategoryScale, Legend, Tooltip,
} from 'chart.js';
import { h, note } from '../../shared/dom.js';
import { isNum } from '../../shared/format.js';
import { GROUND_TRUTH_COLOR } from './colors.js';

Chart.register(ScatterController, BarController, LineElement, PointElement, BarElement,
  LinearScale, CategoryScale, Legend, Tooltip);

Chart.defaults.animation = false;
Chart.defaults.font.family = 'system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif';
Chart.defaults.font.size = 12;
Chart.defaults.color = '#444';
Chart.defaults.borderColor = '#e3e6ea';

const MAX_POINTS = 2500; // per series; longer series are thinned for drawing
const Y_AXIS_WIDTH = 58;
const X_AXIS_HEIGHT = 46;
const PADDING = 8;

// ---------------------------------------------------------------- data helpers

function validPoint(p) {
  return Array.isArray(p) && p.length >= 3 && isNum(p[0]) && isNum(p[1]) && isNum(p[2]);
}

// Keeps every k-th index so a series has at most MAX_POINTS points (the last one included).
function thinIndices(n) {
  const step = Math.max(1, Math.ceil(n / MAX_POINTS));
  const out = [];
  for (let i = 0; i < n; i += step) out.push(i);
  if (n > 0 && out[out.length - 1] !== n - 1) out.push(n - 1);
  return out;
}

// A series of timed 3D positions: {t: [...], p: [[x,y,z], ...]} -> cleaned, thinned arrays.
function timedSeries(src) {
  if (!src || !Array.isArray(src.p)) return null;
  const t = Array.isArray(src.t) ? src.t : [];
  const n = src.p.length;
  const keep = [];
  for (const i of thinIndices(n)) {
    if (validPoint(src.p[i])) keep.push(i);
  }
  if (keep.length < 2) return null;
  return {
    t: keep.map((i) => (isNum(t[i]) ? t[i] : i)),
    p: keep.map((i) => src.p[i]),
    idx: keep,
  };
}

// Time origin of a sequence: earliest timestamp over ground truth and estimates.
function timeOrigin(series) {
  let t0 = Infinity;
  for (const s of series) if (s && s.t.length && s.t[0] < t0) t0 = s.t[0];
  return Number.isFinite(t0) ? t0 : 0;
}

// ---------------------------------------------------------------- legend

// An HTML legend whose entries toggle the datasets with the same key in several charts.
function htmlLegend(items, charts, onChange) {
  const buttons = items.map((item) => {
    const button = h('button', {
      type: 'button', class: 'legend-item', 'aria-pressed': 'true', title: item.title || null,
      onclick: () => {
        const visible = button.getAttribute('aria-pressed') !== 'true';
        button.setAttribute('aria-pressed', String(visible));
        for (const chart of charts) {
          chart.data.datasets.forEach((ds) => {
            if (ds.key === item.key) ds.hidden = !visible;
          });
        }
        if (onChange) onChange();
        for (const chart of charts) chart.update('none');
      },
    },
    h('span', { class: `legend-line${item.dashed ? ' dashed' : ''}`, style: { borderColor: item.color } }),
    item.label);
    return button;
  });
  return h('div', { class: 'legend', role: 'group', 'aria-label': 'Show or hide series' }, buttons);
}

// ---------------------------------------------------------------- equal axis scaling

// Sets both linear scales of a chart so one metre takes the same number of pixels on
// x and y. The axis boxes have fixed sizes, so the plot area is known before layout;
// afterLayout corrects the estimate once if it was off.
function equalScaleOptions(state) {
  const limits = (scale) => {
    const chart = scale.chart;
    const b = state.bounds;
    if (!b) return;
    const corr = chart.$equalCorrection || { w: 0, h: 0 };
    const w = Math.max(10, chart.width - Y_AXIS_WIDTH - 2 * PADDING - corr.w);
    const hgt = Math.max(10, chart.height - X_AXIS_HEIGHT - 2 * PADDING - corr.h);
    const perPixel = Math.max((b.xmax - b.xmin) / w, (b.ymax - b.ymin) / hgt);
    const cx = (b.xmin + b.xmax) / 2;
    const cy = (b.ymin + b.ymax) / 2;
    chart.$equalAssumed = { w, h: hgt };
    if (scale.axis === 'x') {
      scale.min = cx - (perPixel * w) / 2;
      scale.max = cx + (perPixel * w) / 2;
    } else {
      scale.min = cy - (perPixel * hgt) / 2;
      scale.max = cy + (perPixel * hgt) / 2;
    }
  };
  return { afterDataLimits: limits, afterBuildTicks: roundTicks };
}

const equalAxesPlugin = {
  id: 'mcslamEqualAxes',
  afterLayout(chart) {
    const assumed = chart.$equalAssumed;
    const area = chart.chartArea;
    if (!assumed || !area) return;
    const dw = assumed.w - (area.right - area.left);
    const dh = assumed.h - (area.bottom - area.top);
    if ((Math.abs(dw) > 0.5 || Math.abs(dh) > 0.5) && (chart.$equalRetries || 0) < 3) {
      const corr = chart.$equalCorrection || { w: 0, h: 0 };
      chart.$equalCorrection = { w: corr.w + dw, h: corr.h + dh };
      chart.$equalRetries = (chart.$equalRetries || 0) + 1;
      queueMicrotask(() => chart.update('none'));
    } else {
      chart.$equalRetries = 0;
    }
  },
};

// Ticks at round values (1, 2 or 5 × 10^k apart) inside the scale's range; Chart.js
// would start them at the range's (arbitrary) minimum.
function roundTicks(scale) {
  const { min, max } = scale;
  const length = scale.isHorizontal() ? scale.width || scale.chart.width : scale.height || scale.chart.height;
  const wanted = Math.max(3, Math.min(10, Math.floor(length / 70)));
  const raw = (max - min) / wanted;
  const power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw) || 10 * power;
  const ticks = [];
  for (let v = Math.ceil(min / step) * step; v <= max + step * 1e-9; v += step) {
    ticks.push({ value: Math.abs(v) < step * 1e-9 ? 0 : Number(v.toPrecision(12)) });
  }
  scale.ticks = ticks;
}
const EQUAL_TICKS = { autoSkip: false };

function fixedAxisSize(scale) {
  if (scale.axis === 'x') scale.height = X_AXIS_HEIGHT;
  else scale.width = Y_AXIS_WIDTH;
}

function boundsOf(datasets, padFraction) {
  let xmin = Infinity, xmax = -Infinity, ymin = Infinity, ymax = -Infinity;
  for (const ds of datasets) {
    if (ds.hidden) continue;
    for (const pt of ds.data) {
      if (pt.x < xmin) xmin = pt.x;
      if (pt.x > xmax) xmax = pt.x;
      if (pt.y < ymin) ymin = pt.y;
      if (pt.y > ymax) ymax = pt.y;
    }
  }
  if (!Number.isFinite(xmin)) return null;
  const span = Math.max(xmax - xmin, ymax - ymin, 0.05);
  const pad = span * padFraction;
  return { xmin: xmin - pad, xmax: xmax + pad, ymin: ymin - pad, ymax: ymax + pad };
}

// ---------------------------------------------------------------- common options

function tooltipLabel(unit, xName) {
  return (ctx) => {
    const label = ctx.dataset.label || '';
    const { x, y } = ctx.parsed;
    return `${label}: ${y.toFixed(4)} ${unit} at ${xName} ${x.toFixed(xName === 't' ? 2 : 4)}`;
  };
}

function axisTitle(textValue) {
  return { display: true, text: textValue, font: { size: 12 } };
}

function lineDataset(key, label, color, data, extra = {}) {
  return {
    key, label, data, borderColor: color, backgroundColor: color,
    showLine: true, pointRadius: 0, pointHitRadius: 4, borderWidth: 1.5, tension: 0, spanGaps: false,
    ...extra,
  };
}

function canvasBox(kind, seqIndex, extraClass) {
  const canvas = h('canvas', { dataset: { chart: kind, seq: String(seqIndex) }, role: 'img', 'aria-label': kind });
  return { canvas, box: h('div', { class: `chart-box ${extraClass || ''}` }, canvas) };
}

// ---------------------------------------------------------------- trajectories

const PROJECTIONS = {
  xy: { label: 'x–y', a: 0, b: 1 },
  xz: { label: 'x–z', a: 0, b: 2 },
  yz: { label: 'y–z', a: 1, b: 2 },
};
const AXES = ['x', 'y', 'z'];

// Series shown in the trajectory and ATE charts: ground truth first, then each config.
function collectSeries(seq, ctx) {
  const gt = timedSeries(seq.groundtruth);
  const configs = [];
  for (const res of seq.results || []) {
    if (!res || res.skipped || !res.trajectory) continue;
    const s = timedSeries(res.trajectory);
    if (!s) continue;
    const err = Array.isArray(res.trajectory.ate_error_m) ? res.trajectory.ate_error_m : null;
    configs.push({
      key: res.config,
      label: ctx.config(res.config).label || res.config,
      run: res.trajectory.run,
      color: ctx.color(res.config),
      series: s,
      error: err ? s.idx.map((i) => (isNum(err[i]) ? err[i] : null)) : null,
    });
  }
  return { gt, configs };
}

// Returns {element, mount} for the trajectory part (mount() creates the charts once the
// element is in the document), or a note and no mount when there is nothing to plot.
export function trajectoryPart(seq, seqIndex, ctx) {
  const { gt, configs } = collectSeries(seq, ctx);
  if (!configs.length && !gt) {
    return { element: note('No trajectory to plot: no successful sequential run.'), mount: null };
  }
  const t0 = timeOrigin([gt, ...configs.map((c) => c.series)]);
  const all = [];
  if (gt) all.push({ key: '__gt', label: 'ground truth', color: GROUND_TRUTH_COLOR, dashed: true, series: gt, width: 2 });
  for (const c of configs) all.push({ ...c, width: 1.5, title: c.run ? `run ${c.run}` : null });

  // The DOM is built first; the charts are created by mount() once it is in the document.
  const state = { bounds: null };
  const charts = [];
  const top = canvasBox('trajectory-top', seqIndex, 'chart-top');
  const axisBoxes = AXES.map((axis) => canvasBox(`trajectory-${axis}`, seqIndex, 'chart-axis'));
  const project = (s, proj) => s.p.map((p) => ({ x: p[PROJECTIONS[proj].a], y: p[PROJECTIONS[proj].b] }));
  const aspectFor = (b) => (b ? Math.min(2.0, Math.max(0.9, (b.xmax - b.xmin) / (b.ymax - b.ymin))) : 1.4);
  const refreshBounds = () => {
    if (charts[0]) state.bounds = boundsOf(charts[0].data.datasets, 0.04) || state.bounds;
  };

  const setProjection = (proj) => {
    const topChart = charts[0];
    if (!topChart) return;
    topChart.data.datasets.forEach((ds, i) => {
      ds.data = project(all[i].series, proj);
    });
    const { a, b } = PROJECTIONS[proj];
    topChart.options.scales.x.title.text = `${AXES[a]} (m)`;
    topChart.options.scales.y.title.text = `${AXES[b]} (m)`;
    refreshBounds();
    topChart.options.aspectRatio = aspectFor(state.bounds);
    topChart.resize();
    topChart.update('none');
  };

  const mount = () => {
    const topDatasets = all.map((s) => lineDataset(s.key, s.label, s.color, project(s.series, 'xy'),
      { borderWidth: s.width, borderDash: s.dashed ? [6, 4] : undefined }));
    state.bounds = boundsOf(topDatasets, 0.04);
    const equal = equalScaleOptions(state);
    charts.push(new Chart(top.canvas, {
      type: 'scatter',
      data: { datasets: topDatasets },
      plugins: [equalAxesPlugin],
      options: {
        responsive: true, maintainAspectRatio: true, aspectRatio: aspectFor(state.bounds),
        layout: { padding: PADDING },
        interaction: { mode: 'nearest', intersect: false },
        plugins: { legend: { display: false }, tooltip: { callbacks: { label: tooltipLabel('m', 'x') } } },
        scales: {
          x: { type: 'linear', bounds: 'data', title: axisTitle('x (m)'), afterFit: fixedAxisSize, ticks: EQUAL_TICKS, ...equal },
          y: { type: 'linear', bounds: 'data', title: axisTitle('y (m)'), afterFit: fixedAxisSize, ticks: EQUAL_TICKS, ...equal },
        },
      },
    }));
    AXES.forEach((axis, k) => {
      charts.push(new Chart(axisBoxes[k].canvas, {
        type: 'scatter',
        data: {
          datasets: all.map((s) => lineDataset(s.key, s.label, s.color,
            s.series.p.map((p, i) => ({ x: s.series.t[i] - t0, y: p[k] })),
            { borderWidth: s.width, borderDash: s.dashed ? [6, 4] : undefined })),
        },
        options: {
          responsive: true, maintainAspectRatio: false,
          layout: { padding: { left: 4, right: 8, top: 4, bottom: 0 } },
          interaction: { mode: 'nearest', intersect: false },
          plugins: { legend: { display: false }, tooltip: { callbacks: { label: tooltipLabel('m', 't') } } },
          scales: {
            x: { type: 'linear', title: axisTitle('time (s)'), ticks: { maxTicksLimit: 8 } },
            y: { type: 'linear', title: axisTitle(`${axis} (m)`), ticks: { maxTicksLimit: 5 } },
          },
        },
      }));
    });
    return charts;
  };

  const select = h('select', {
    'aria-label': 'Projection of the top view',
    dataset: { control: 'projection' },
    onchange: (e) => setProjection(e.target.value),
  }, Object.entries(PROJECTIONS).map(([value, p]) => h('option', { value }, p.label)));

  const legend = htmlLegend(all, charts, refreshBounds);
  const hint = gt
    ? 'Estimates are aligned into the ground-truth frame; the top view has equal scales on both axes. Click a legend entry to hide or show it.'
    : 'No ground truth: each estimate is in its own frame. Click a legend entry to hide or show it.';
  const element = h('div', { class: 'trajectory' },
    h('div', { class: 'toolbar' }, legend, h('label', { class: 'control' }, 'Top view ', select)),
    h('div', { class: 'trajectory-grid' },
      h('div', { class: 'trajectory-top' }, top.box),
      h('div', { class: 'trajectory-axes' }, axisBoxes.map((b) => b.box))),
    h('p', { class: 'hint' }, hint));
  return { element, mount };
}

// ---------------------------------------------------------------- ATE over time

export function atePart(seq, seqIndex, ctx) {
  const { gt, configs } = collectSeries(seq, ctx);
  const withError = configs.filter((c) => c.error && c.error.some(isNum));
  if (!withError.length) {
    const why = seq.groundtruth ? 'no per-pose ATE error in the data.' : 'there is no ground truth for this sequence.';
    return { element: note(`No ATE error over time: ${why}`), mount: null };
  }
  const t0 = timeOrigin([gt, ...configs.map((c) => c.series)]);
  const box = canvasBox('ate-time', seqIndex, 'chart-wide');
  const charts = [];
  const mount = () => {
    charts.push(new Chart(box.canvas, {
      type: 'scatter',
      data: {
        datasets: withError.map((c) => lineDataset(c.key, c.label, c.color,
          c.series.t.map((t, i) => ({ x: t - t0, y: c.error[i] })).filter((pt) => isNum(pt.y)))),
      },
      options: {
        responsive: true, maintainAspectRatio: false,
        layout: { padding: PADDING },
        interaction: { mode: 'nearest', intersect: false },
        plugins: { legend: { display: false }, tooltip: { callbacks: { label: tooltipLabel('m', 't') } } },
        scales: {
          x: { type: 'linear', title: axisTitle('time (s)') },
          y: { type: 'linear', beginAtZero: true, title: axisTitle('ATE error (m)') },
        },
      },
    }));
    return charts;
  };
  const element = h('div', { class: 'ate' },
    h('div', { class: 'toolbar' }, htmlLegend(withError, charts)),
    box.box,
    h('p', { class: 'hint' }, 'Distance between each estimated position and the ground truth at the same time, for the plotted run of each config.'));
  return { element, mount };
}

// ---------------------------------------------------------------- stage timing

// Merges the stage lists of several configs into one order that respects each list.
function mergeStageOrder(lists) {
  const order = [];
  for (const list of lists) {
    let insertAt = 0;
    for (const name of list) {
      const at = order.indexOf(name);
      if (at >= 0) insertAt = at + 1;
      else order.splice(insertAt++, 0, name);
    }
  }
  return order;
}

// Splits text at spaces into lines of at most `width` characters (longer words stay whole).
function wrapWords(textValue, width) {
  const lines = [];
  for (const word of String(textValue).split(/\s+/)) {
    const last = lines.length - 1;
    if (last >= 0 && lines[last].length + 1 + word.length <= width) lines[last] += ` ${word}`;
    else lines.push(word);
  }
  return lines;
}

export function timingPart(seq, seqIndex, ctx) {
  const rows = [];
  for (const res of seq.results || []) {
    if (!res || res.skipped || !Array.isArray(res.stages_ms)) continue;
    const stages = res.stages_ms.filter((s) => Array.isArray(s) && s.length >= 2 && isNum(s[1]));
    if (!stages.length) continue;
    rows.push({ config: res.config, stages: new Map(stages.map(([n, v]) => [String(n), v])), order: stages.map((s) => String(s[0])) });
  }
  if (!rows.length) return { element: note('No per-stage timing: no successful threaded run.'), mount: null };
  const stageNames = mergeStageOrder(rows.map((r) => r.order));
  const total = (r) => [...r.stages.values()].reduce((a, b) => a + b, 0);
  // Multi-line labels: the config (long names wrapped), then the sum of its stages.
  const labels = rows.map((r) => [...wrapWords(ctx.config(r.config).label || r.config, 18), `${total(r).toFixed(1)} ms`]);
  const box = canvasBox('timing', seqIndex, 'chart-timing');
  box.box.style.height = `${Math.max(170, 80 + labels.reduce((sum, l) => sum + 16 + 14 * l.length, 0))}px`;
  const mount = () => [new Chart(box.canvas, {
    type: 'bar',
    data: {
      labels,
      datasets: stageNames.map((name) => ({
        label: name,
        data: rows.map((r) => (r.stages.has(name) ? r.stages.get(name) : null)),
        backgroundColor: ctx.stageColor(name),
        borderColor: '#ffffff',
        borderWidth: 1,
        barPercentage: 0.8,
        categoryPercentage: 0.9,
      })),
    },
    options: {
      indexAxis: 'y', responsive: true, maintainAspectRatio: false,
      layout: { padding: PADDING },
      plugins: {
        legend: { position: 'top', labels: { boxWidth: 14, boxHeight: 10 } },
        tooltip: { callbacks: { label: (c) => `${c.dataset.label}: ${c.parsed.x.toFixed(1)} ms` } },
      },
      scales: {
        x: { type: 'linear', stacked: true, beginAtZero: true, title: axisTitle('median time per frame (ms)') },
        y: { type: 'category', stacked: true, grid: { display: false }, ticks: { autoSkip: false } },
      },
    },
  })];
  const element = h('div', { class: 'timing' }, box.box,
    h('p', { class: 'hint' }, 'Median milliseconds per frame for each stage in the threaded runs, in pipeline order; the sum of the stages is under each config.'));
  return { element, mount };
}
