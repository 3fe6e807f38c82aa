// Annotated frames: a gallery of the overlay JPEGs with captions; click to enlarge.
import { h, note } from '../../shared/dom.js';
import { isNum } from '../../shared/format.js';

let viewer = null;

// One <dialog> for the whole page shows an enlarged frame.
function openViewer(src, caption) {
  if (!viewer) {
    const img = h('img', { alt: '' });
    const cap = h('p', { class: 'viewer-caption' });
    viewer = h('dialog', { class: 'viewer', onclick: () => viewer.close() },
      img, cap, h('p', { class: 'hint' }, 'Click or press Esc to close.'));
    viewer.$img = img;
    viewer.$cap = cap;
    document.body.append(viewer);
  }
  viewer.$img.src = src;
  viewer.$img.alt = caption;
  viewer.$cap.textContent = caption;
  if (typeof viewer.showModal === 'function') viewer.showModal();
  else viewer.setAttribute('open', '');
}

// Returns {element, mount}; mount() resolves when every image has decoded (or failed).
export function galleryPart(seq, seqIndex) {
  const overlays = (Array.isArray(seq.overlays) ? seq.overlays : [])
    .filter((o) => o && typeof o.jpeg_base64 === 'string' && o.jpeg_base64.length > 0);
  if (!overlays.length) return { element: note('No annotated frames for this sequence.'), mount: null };

  const figures = overlays.map((o) => {
    const caption = o.caption ? String(o.caption) : (isNum(o.frame) ? `frame ${o.frame}` : 'annotated frame');
    const src = `data:image/jpeg;base64,${o.jpeg_base64.replace(/\s+/g, '')}`;
    const img = h('img', { src, alt: caption, dataset: { overlay: String(seqIndex) } });
    const frameKnown = isNum(o.frame) && !caption.includes(`frame ${o.frame}`);
    const detail = [frameKnown ? `frame ${o.frame}` : null, isNum(o.timestamp) ? `timestamp ${o.timestamp.toFixed(3)} s` : null]
      .filter(Boolean).join(' · ');
    const fig = h('figure', { class: 'frame' },
      h('button', { type: 'button', class: 'frame-open', title: 'Enlarge', onclick: () => openViewer(src, caption) }, img),
      h('figcaption', null, caption, detail ? h('span', { class: 'sub' }, detail) : null));
    return { fig, img, caption };
  });

  const mount = () => figures.map(({ fig, img, caption }) => img.decode().catch((err) => {
    console.warn(`mcslam report: could not decode the overlay image "${caption}":`, err);
    fig.replaceWith(h('figure', { class: 'frame' }, note(`Could not show the image "${caption}".`, 'error')));
  }));
  return { element: h('div', { class: 'gallery' }, figures.map((f) => f.fig)), mount };
}
