// decollage view: the gallery of one build folder (studio/gallery.py serves /api/manifest and /files/...).
import { Viewer, nodeRole, el, getJSON, fmtBytes } from '/static/viewer3d.js';

const studio = (window.studio = { ready: false, shown: null, cards: 0, error: null });
const $ = (id) => document.getElementById(id);
const viewer = new Viewer($('viewer'));
studio.viewer = viewer;
let manifest = null;
let selected = null;
let shownScene = null;

const fileUrl = (path) => '/files/' + path.split('/').map(encodeURIComponent).join('/');
const stylesOf = (a) => (a.coarse_grid && a.coarse_grid.styles) || [];
const num = (v, d = 2) => (v == null ? '' : Number(v).toFixed(d));

function sizeOf(a) {
  const m = a.mesh;
  if (!m || !m.bbox_min_m) return '';
  return m.bbox_max_m.map((hi, i) => (hi - m.bbox_min_m[i]).toFixed(2)).join(' × ') + ' m';
}

function totalTime(a) {
  const t = a.timings_s || {};
  return Object.values(t).reduce((s, v) => s + v, 0);
}

function figures(a) {
  if (a.status !== 'built') return [];
  const parts = [];
  if (a.mesh) parts.push(`${a.mesh.triangles.toLocaleString('en')} tris`);
  parts.push(sizeOf(a));
  if (a.structure) parts.push(`IOU ${num(a.structure.strict_iou)}/${num(a.structure.loose_iou)}`);
  parts.push(`${totalTime(a).toFixed(1)} s`);
  return parts.filter(Boolean);
}

function card(a) {
  const png = a.outputs && (a.outputs.preview || a.outputs.png);
  const failed = a.status !== 'built';
  const node = el('article', { class: 'card' + (failed ? ' failed' : ''), tabindex: 0, 'data-name': a.name,
    onclick: () => select(a), onkeydown: (e) => { if (e.key === 'Enter') select(a); } },
    png ? el('img', { src: fileUrl(png.path), alt: `preview of ${a.name}`, loading: 'lazy' })
        : el('div', { class: 'no-preview', text: failed ? 'failed' : 'no preview' }),
    el('h3', { text: a.name }),
    el('p', { class: 'figures', text: figures(a).join(' · ') }),
    el('p', { class: 'chips' }, stylesOf(a).map((s) => el('span', { class: 'chip', text: s }))),
    failed ? el('p', { class: 'error-text', text: a.error || 'failed (no message)' }) : null,
    (a.warnings || []).length ? el('p', { class: 'warn-text', text: `${a.warnings.length} warning(s)` }) : null);
  a._card = node;
  return node;
}

function row(label, value) {
  if (value == null || value === '') return null;
  return el('tr', {}, el('th', { text: label }), el('td', {}, value));
}

function details(a) {
  const box = $('details');
  box.replaceChildren();
  const m = a.mesh || {};
  const det = a.detailizer || {};
  const t = a.timings_s || {};
  const outputs = Object.entries(a.outputs || {}).map(([kind, o]) =>
    el('a', { href: fileUrl(o.path), text: `${kind} (${fmtBytes(o.bytes)})`, download: o.path.split('/').pop() }));
  box.append(el('table', { class: 'figures-table' },
    row('status', a.status),
    row('source', a.source_kind),
    row('variant', a.variant ? Object.entries(a.variant).map(([k, v]) => `${k}=${v}`).join(' ') : null),
    row('detailizer', det.name ? `${det.name}${det.learned ? ' (learned)' : ''}` : null),
    row('triangles', m.triangles != null ? m.triangles.toLocaleString('en') : null),
    row('LOD triangles', a.engine && a.engine.lod_triangles ? a.engine.lod_triangles.join(' / ') : null),
    row('vertices', m.vertices != null ? m.vertices.toLocaleString('en') : null),
    row('size', sizeOf(a)),
    row('watertight', m.watertight == null ? null : String(m.watertight)),
    row('Strict-IOU', a.structure ? num(a.structure.strict_iou, 4) : null),
    row('Loose-IOU', a.structure ? num(a.structure.loose_iou, 4) : null),
    row('coarse grid', a.coarse_grid ? `${a.coarse_grid.shape.join('×')} (${a.coarse_grid.occupied} occupied)` : null),
    row('parts', a.coarse_grid ? a.coarse_grid.parts.join(', ') : null),
    row('styles', stylesOf(a).join(', ')),
    row('engine', a.engine ? `${a.engine.profile}, collision ${a.engine.collision}` : null),
    row('time', Object.keys(t).length ? `${totalTime(a).toFixed(2)} s (` +
      Object.entries(t).map(([k, v]) => `${k} ${v.toFixed(2)}`).join(', ') + ')' : null),
    row('files', outputs.length ? el('span', { class: 'links' }, outputs) : null)));
  if (a.error) box.append(el('p', { class: 'error-text', text: a.error }));
  if ((a.warnings || []).length) box.append(el('ul', { class: 'warnings' }, a.warnings.map((w) => el('li', { text: w }))));
}

function applyVisibility() {
  if (!shownScene) return;
  const lod = Number($('lod').value || 0);
  const collision = $('collision').checked;
  shownScene.traverse((o) => {
    if (!o.isMesh) return;
    let role = { collision: false, lod: 0 };
    for (let p = o; p; p = p.parent) {
      if (p.name && (nodeRole(p.name).collision || /_LOD\d+$/.test(p.name))) { role = nodeRole(p.name); break; }
    }
    o.visible = role.collision ? collision : role.lod === lod;
    if (role.collision) { o.material.wireframe = true; o.material.vertexColors = false; o.material.color.set(0x7fd1ff); }
  });
  viewer.render();
}

function fillLods(scene) {
  const levels = new Set([0]);
  scene.traverse((o) => { const r = nodeRole(o.name || ''); if (!r.collision) levels.add(r.lod); });
  $('lod').replaceChildren(...[...levels].sort((x, y) => x - y).map((l) => el('option', { value: l, text: l })));
}

async function select(a, { version = '' } = {}) {
  selected = a;
  for (const c of document.querySelectorAll('.card.selected')) c.classList.remove('selected');
  a._card.classList.add('selected');
  $('viewer-title').textContent = a.name;
  details(a);
  const glb = a.outputs && a.outputs.glb;
  if (a.status !== 'built' || !glb) {
    shownScene = null;
    viewer.show(null);
    studio.shown = null;
    return;
  }
  try {
    const scene = await viewer.loadGLB(fileUrl(glb.path) + (version ? `?v=${version}` : ''));
    if (selected !== a) return;  // another card was chosen meanwhile
    shownScene = scene;
    fillLods(scene);
    viewer.show(scene, { keepView: !!version });
    applyVisibility();
    if (!version) viewer.frame();
    studio.shown = a.name;
  } catch (err) {
    showError(`cannot load ${glb.path}: ${err.message}`);
  }
}

function applyFilter() {
  const text = $('filter').value.trim().toLowerCase();
  const style = $('style-filter').value;
  const status = $('status-filter').value;
  let shown = 0;
  for (const a of manifest.assets) {
    const styles = stylesOf(a);
    const ok = (!text || a.name.toLowerCase().includes(text) || styles.some((s) => s.toLowerCase().includes(text)))
      && (!style || styles.includes(style)) && (!status || a.status === status);
    a._card.hidden = !ok;
    shown += ok;
  }
  $('shown-count').textContent = `${shown} of ${manifest.assets.length} shown`;
  studio.visibleCards = shown;
}

function showError(message) {
  studio.error = message;
  $('error').hidden = false;
  $('error').textContent = message;
}

function showManifest() {
  const s = manifest.summary || {};
  $('folder').textContent = manifest.studio.folder;
  document.title = `decollage view: ${manifest.studio.folder}`;
  $('summary').textContent = `${manifest.assets.length} assets · ${s.built ?? '?'} built · ${s.failed ?? '?'} failed`
    + (manifest.recipe ? ` · recipe ${manifest.recipe.path}` : '') + (manifest.tool ? ` · decollage ${manifest.tool.version}` : '')
    + (studio.buildCounter ? ` · build #${studio.buildCounter}` : '');
  const styles = [...new Set(manifest.assets.flatMap(stylesOf))].sort();
  const chosen = $('style-filter').value;
  $('style-filter').replaceChildren(el('option', { value: '', text: 'all styles' }),
    ...styles.map((st) => el('option', { value: st, text: st })));
  $('style-filter').value = styles.includes(chosen) ? chosen : '';
  $('cards').replaceChildren(...manifest.assets.map(card));
  studio.cards = manifest.assets.length;
  applyFilter();
}

// A build into the folder (decollage build, or --watch) bumps build.json's counter: reload what changed.
let following = false;
async function followBuilds() {
  if (following || document.visibilityState !== 'visible') return;
  following = true;
  try { await refreshIfRebuilt(); } finally { following = false; }
}

async function refreshIfRebuilt() {
  let signal;
  try { signal = await getJSON('/api/build'); } catch { return; }
  if (signal.counter === studio.buildCounter) return;
  studio.buildCounter = signal.counter;
  manifest = await getJSON('/api/manifest');
  const name = selected && selected.name;
  showManifest();
  const again = manifest.assets.find((a) => a.name === name);
  if (again) await select(again, { version: signal.rebuilt.includes(name) ? String(signal.counter) : '' });
  studio.refreshes = (studio.refreshes || 0) + 1;
}

async function main() {
  studio.buildCounter = (await getJSON('/api/build')).counter;
  manifest = await getJSON('/api/manifest');
  showManifest();
  for (const id of ['filter', 'style-filter', 'status-filter']) $(id).addEventListener('input', applyFilter);
  $('lod').addEventListener('change', applyVisibility);
  $('collision').addEventListener('change', applyVisibility);
  studio.ready = true;
  const first = manifest.assets.find((a) => a.status === 'built') || manifest.assets[0];
  if (first) await select(first);
  setInterval(() => followBuilds().catch((err) => showError(err.message)), 1500);
}

main().catch((err) => showError(err.message));
