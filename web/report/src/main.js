// Entry point of the mcslam bench report. Reads the JSON in #mcslam-data and builds
// the whole page; sets body[data-ready="true"] once everything has rendered.
import css from './style.css';
import { h, append, note, guarded, slug } from '../../shared/dom.js';
import { makeConfigColors, makeStageColors } from './colors.js';
import {
  header, overview, sequenceCards, sequenceMeta, ablationTable, runDetails,
  publishedTables, failedRuns, markdown,
} from './tables.js';
import { trajectoryPart, atePart, timingPart } from './charts.js';
import { galleryPart } from './gallery.js';
import { gridPart } from './grid.js';
import { mapPart } from './map3d.js';

const FORMAT = 'mcslam-bench-report';
const VERSION = 1;

function injectStyle() {
  document.head.append(h('style', null, css));
}

function readData() {
  const el = document.getElementById('mcslam-data');
  if (!el) throw new Error('the page has no #mcslam-data element');
  const data = JSON.parse(el.textContent);
  if (!data || typeof data !== 'object') throw new Error('the data is not a JSON object');
  return data;
}

function makeContext(data) {
  const configs = (Array.isArray(data.configs) ? data.configs : []).filter((c) => c && c.name);
  const byName = new Map(configs.map((c) => [c.name, c]));
  const sequences = Array.isArray(data.sequences) ? data.sequences.filter(Boolean) : [];
  return {
    configs,
    sequences,
    config: (name) => byName.get(name) || { name, label: name },
    color: makeConfigColors(configs),
    stageColor: makeStageColors(sequences),
    fullConfig: byName.has('full') ? 'full' : (configs.length ? configs[configs.length - 1].name : 'full'),
    sequenceId: (i) => slug(sequences[i] && sequences[i].name, i),
  };
}

// A titled block of a sequence whose content may need mounting once in the document.
function block(title, part, mounts, what) {
  const body = h('div', { class: 'part-body' }, part.element);
  if (part.mount) mounts.push({ what, body, mount: part.mount });
  return h('section', { class: 'part' }, h('h3', null, title), body);
}

// Builds a part with guarded(); a failure becomes a message in its place.
function safePart(what, build) {
  let part = null;
  const element = guarded(what, () => {
    part = build();
    return part.element;
  });
  return part && part.element === element ? part : { element, mount: null };
}

function sequenceSection(seq, i, ctx, mounts) {
  const name = seq.name ? String(seq.name) : `sequence ${i + 1}`;
  const id = ctx.sequenceId(i);
  const results = Array.isArray(seq.results) ? seq.results : [];
  const hasPublished = Array.isArray(seq.published) && seq.published.length > 0;
  const hasOverlays = Array.isArray(seq.overlays) && seq.overlays.length > 0;

  const parts = [
    h('section', { class: 'part' }, h('h3', null, 'Ablation'),
      guarded(`the ablation table of ${name}`, () => ablationTable(seq, ctx)),
      guarded(`the run details of ${name}`, () => runDetails(seq, ctx))),
    hasPublished ? h('section', { class: 'part' }, h('h3', null, 'Published figures beside ours'),
      guarded(`the published figures of ${name}`, () => publishedTables(seq, ctx))) : null,
    block('Trajectories', safePart(`the trajectory plots of ${name}`, () => trajectoryPart(seq, i, ctx)), mounts, `the trajectory plots of ${name}`),
    block('ATE error over time', safePart(`the ATE plot of ${name}`, () => atePart(seq, i, ctx)), mounts, `the ATE plot of ${name}`),
    block('Per-stage timing', safePart(`the timing chart of ${name}`, () => timingPart(seq, i, ctx)), mounts, `the timing chart of ${name}`),
    hasOverlays ? block('Annotated frames', safePart(`the annotated frames of ${name}`, () => galleryPart(seq, i)), mounts, `the annotated frames of ${name}`) : null,
    block('3D map', safePart(`the 3D map of ${name}`, () => mapPart(seq, i)), mounts, `the 3D map of ${name}`),
    block('Occupancy grid', safePart(`the occupancy grid of ${name}`, () => gridPart(seq, i)), mounts, `the occupancy grid of ${name}`),
  ];
  return h('section', { class: 'sequence', id, dataset: { seq: String(i), sequence: name } },
    h('h2', null, name, seq.dataset ? h('span', { class: 'tag' }, String(seq.dataset)) : null,
      h('span', { class: 'tag tag-light' }, `${results.length} config${results.length === 1 ? '' : 's'}`)),
    seq.path ? h('p', { class: 'seq-path' }, h('code', null, String(seq.path))) : null,
    h('div', { class: 'sequence-summary' },
      guarded(`the summary of ${name}`, () => sequenceMeta(seq)),
      guarded(`the summary cards of ${name}`, () => sequenceCards(seq, ctx))),
    parts);
}

function navigation(ctx) {
  const links = ctx.sequences.map((seq, i) => h('a', { href: `#${ctx.sequenceId(i)}` }, String(seq.name || `sequence ${i + 1}`)));
  return h('nav', { class: 'page-nav', 'aria-label': 'Sections' },
    ctx.sequences.length > 1 ? h('a', { href: '#overview' }, 'Overview') : null,
    links,
    h('a', { href: '#failed-runs' }, 'Failed runs'),
    h('a', { href: '#markdown' }, 'Markdown'));
}

function build(root, data) {
  const ctx = makeContext(data);
  const mounts = [];
  if (data.format !== FORMAT || data.version !== VERSION) {
    console.warn(`mcslam report: expected ${FORMAT} version ${VERSION}, got ${data.format} version ${data.version}`);
    root.append(note(`This page expects ${FORMAT} version ${VERSION} but the data says ${data.format || '?'} version ${data.version ?? '?'}; some parts may be missing.`, 'error'));
  }
  append(root, [
    guarded('the header', () => header(data, ctx)),
    navigation(ctx),
    ctx.sequences.length > 1
      ? h('section', { class: 'overview', id: 'overview' }, h('h2', null, 'Overview'), guarded('the overview', () => overview(data, ctx)))
      : null,
    ctx.sequences.length ? null : note('The data has no sequences.', 'error'),
    ctx.sequences.map((seq, i) => sequenceSection(seq, i, ctx, mounts)),
    h('section', { class: 'global', id: 'failed-runs' }, h('h2', null, 'Failed runs'), guarded('the failed runs', () => failedRuns(data))),
    h('section', { class: 'global', id: 'markdown' }, h('h2', null, 'Markdown'), guarded('the Markdown', () => markdown(data))),
    h('footer', { class: 'page-footer' }, `Written by mcslam bench · data format ${data.format || '?'} version ${data.version ?? '?'}`),
  ]);
  return mounts;
}

// Creates the charts, 3D views and images now that the page is laid out; returns the
// promises to wait for (image decoding).
function mountAll(mounts) {
  const waits = [];
  for (const { what, body, mount } of mounts) {
    try {
      const result = mount();
      for (const item of result || []) if (item && typeof item.then === 'function') waits.push(item);
    } catch (err) {
      console.warn(`mcslam report: could not render ${what}:`, err);
      body.replaceChildren(note(`Could not render ${what}: ${err && err.message ? err.message : err}`, 'error'));
    }
  }
  return waits;
}

function nextFrame() {
  return new Promise((resolve) => requestAnimationFrame(() => resolve()));
}

async function start() {
  const root = h('main', { class: 'report' });
  try {
    injectStyle();
    document.body.append(root);
    let data;
    try {
      data = readData();
    } catch (err) {
      console.warn('mcslam report: could not read the data:', err);
      root.append(h('h1', null, 'mcslam bench report'), note(`Could not read the report data: ${err.message}`, 'error'));
      return;
    }
    const waits = mountAll(build(root, data));
    await Promise.allSettled(waits);
    // Let pending chart/3D updates (scheduled for the next frame) happen first.
    await nextFrame();
    await nextFrame();
  } catch (err) {
    console.warn('mcslam report: unexpected error:', err);
    root.append(note(`Something went wrong while building the page: ${err && err.message ? err.message : err}`, 'error'));
  } finally {
    document.body.dataset.ready = 'true';
  }
}

if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
else start();
