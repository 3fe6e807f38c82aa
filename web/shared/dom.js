// Tiny DOM helpers. All text from the data goes through textContent, never innerHTML.

// h('div', {class: 'x', onclick: fn, dataset: {a: 1}}, child, 'text', [more, children])
export function h(tag, attrs, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === null || value === undefined || value === false) continue;
    if (key === 'class') el.className = value;
    else if (key === 'dataset') Object.assign(el.dataset, value);
    else if (key === 'style' && typeof value === 'object') Object.assign(el.style, value);
    else if (key.startsWith('on') && typeof value === 'function') el.addEventListener(key.slice(2), value);
    else if (value === true) el.setAttribute(key, '');
    else el.setAttribute(key, String(value));
  }
  append(el, children);
  return el;
}

// Appends children to el, flattening arrays and skipping null/undefined/false.
export function append(el, children) {
  for (const child of children) {
    if (child === null || child === undefined || child === false) continue;
    if (Array.isArray(child)) append(el, child);
    else el.append(child instanceof Node ? child : String(child));
  }
}

// A readable notice shown in place of a part that has nothing to show.
export function note(message, kind = 'info') {
  return h('p', { class: `note note-${kind}` }, message);
}

// Runs a renderer for one part of the page; on an exception, shows a message in its
// place and warns on the console instead of letting the whole page fail.
export function guarded(what, render) {
  try {
    return render();
  } catch (err) {
    console.warn(`mcslam report: could not render ${what}:`, err);
    return note(`Could not render ${what}: ${err && err.message ? err.message : err}`, 'error');
  }
}

// Stable id fragment for anchors, derived from a sequence name.
export function slug(name, index) {
  const base = String(name || 'sequence').toLowerCase().replace(/[^a-z0-9]+/g, '-').replace(/^-|-$/g, '');
  return `seq-${index}-${base || 'sequence'}`;
}
