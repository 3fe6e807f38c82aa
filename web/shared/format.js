// Number and text formatting shared by every part of the page.

const DASH = '–';

export function isNum(x) {
  return typeof x === 'number' && Number.isFinite(x);
}

// Unit kinds used throughout the report: metres, degrees, ratio (0..1 shown as %),
// frames per second, milliseconds, seconds.
const DIGITS = { m: 4, deg: 2, ratio: 1, fps: 1, ms: 1, s: 1 };
const SUFFIX = { m: ' m', deg: '°', ratio: ' %', fps: ' fps', ms: ' ms', s: ' s' };

// Plain number in the given unit, without the unit suffix.
export function num(x, unit) {
  if (!isNum(x)) return DASH;
  const v = unit === 'ratio' ? x * 100 : x;
  return v.toFixed(DIGITS[unit] ?? 3);
}

// Number with its unit, e.g. "0.0105 m", "31.0 ms", "98.2 %".
export function withUnit(x, unit) {
  return isNum(x) ? num(x, unit) + SUFFIX[unit] : DASH;
}

// "min–max" range of a {median,min,max,n} summary; empty when there is a single run.
export function range(stat, unit) {
  if (!stat || !isNum(stat.min) || !isNum(stat.max)) return '';
  if (stat.n === 1 || stat.min === stat.max) return '';
  return `${num(stat.min, unit)}–${num(stat.max, unit)}`;
}

export function duration(seconds) {
  if (!isNum(seconds)) return DASH;
  if (seconds < 60) return `${seconds.toFixed(1)} s`;
  const h = Math.floor(seconds / 3600);
  const m = Math.floor((seconds % 3600) / 60);
  const s = Math.round(seconds % 60);
  return h > 0 ? `${h} h ${String(m).padStart(2, '0')} min` : `${m} min ${String(s).padStart(2, '0')} s`;
}

export function dateTime(iso) {
  if (typeof iso !== 'string' || !iso) return DASH;
  const d = new Date(iso);
  if (Number.isNaN(d.getTime())) return iso;
  // Shown in UTC so every reader sees the same thing as results.md.
  return d.toISOString().replace('T', ' ').replace(/\.\d+Z$|Z$/, ' UTC');
}

export function text(x) {
  return x === null || x === undefined || x === '' ? DASH : String(x);
}

export { DASH };
