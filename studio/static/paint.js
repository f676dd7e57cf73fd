// decollage paint: paint part labels and styles onto an asset's coarse grid, detailize, save into the recipe.
// The server (studio/painter.py) turns the painted labels into region rules; the page only holds, per occupied
// voxel, the part label and style it wants (indices into partNames / styleNames).
import { Viewer, nodeRole, el, getJSON, postJSON, THREE } from '/static/viewer3d.js';
import { VoxelGrid } from '/static/voxels.js';

const $ = (id) => document.getElementById(id);
const PART_COLORS = [[86, 180, 233], [230, 159, 0], [0, 158, 115], [204, 121, 167], [240, 228, 66], [213, 94, 0],
  [0, 114, 178], [170, 170, 170]];
const KEEP = '(keep)';

const S = {
  session: null, asset: null, count: 0,
  part: null, style: null, partNames: [], styleNames: [], palette: {},
  vocab: { styles: null, parts: null, learned: false }, extraStyles: [], extraParts: [],
  history: [], tool: 'orbit', seq: 0, dirty: false, lastEditAt: null, shownAsset: null,
};
const studio = (window.studio = { ready: false, state: S, result: null, timings: [], saved: null, error: null });

const coarse = new Viewer($('coarse'));
const fine = new Viewer($('fine'));
const grid = new VoxelGrid(coarse);
studio.coarse = coarse;
studio.fine = fine;
// Where voxel i's centre is on screen (client pixels): for scripted use of the brush (tests, benchmarks).
studio.screenOf = (i) => {
  const [x, y, z] = grid.cell(i);
  const v = new THREE.Vector3(x + 0.5, y + 0.5, z + 0.5).project(coarse.camera);
  const rect = coarse.canvas.getBoundingClientRect();
  return [rect.left + (v.x + 1) / 2 * rect.width, rect.top + (1 - v.y) / 2 * rect.height];
};

// ------------------------------------------------------------------ small helpers

function status(text, kind = '') {
  $('status').textContent = text;
  $('status').className = kind;
  if (kind === 'bad') studio.error = text;
}

const styleRGB = (name) => S.palette[name] || [190, 190, 190];
const partRGB = (name) => PART_COLORS[Math.max(0, S.partNames.indexOf(name)) % PART_COLORS.length];
const fail = (err) => status(err.message || String(err), 'bad');

function styleChoices() {
  const own = [...S.styleNames, ...S.extraStyles];
  return [...new Set(S.vocab.styles ? [...S.vocab.styles, ...own.filter((s) => S.vocab.styles.includes(s))] : own)];
}

function partChoices() {
  const own = [...S.partNames, ...S.extraParts];
  return [...new Set(S.vocab.parts ? [...own.filter((p) => S.vocab.parts.includes(p)), ...S.vocab.parts] : own)];
}

function options(select, values, current, extra = []) {
  select.replaceChildren(...extra.map((v) => el('option', { value: v, text: v })),
    ...values.map((v) => el('option', { value: v, text: v })));
  if (current != null) select.value = current;
}

// Palette slots depend on the order the rules give the styles, so the server compiles the labels to say
// which colour each style will have in the GLB (pipeline/palette.py).
async function refreshPalette() {
  if (!S.asset) return;
  S.palette = await postJSON('/api/palette', { asset: S.asset.name, target: target(), extra: styleChoices() });
}

function target() {
  return { part_names: S.partNames, style_names: S.styleNames, part: Array.from(S.part), style: Array.from(S.style) };
}

// ------------------------------------------------------------------ drawing the state

function recolor() {
  const byPart = $('color-by').value === 'part';
  grid.paint((i) => (byPart ? partRGB(S.partNames[S.part[i]]) : styleRGB(S.styleNames[S.style[i]])));
  const used = byPart ? [...new Set(S.part)].map((p) => S.partNames[p]) : [...new Set(S.style)].map((s) => S.styleNames[s]);
  $('legend').replaceChildren(...used.sort().map((n) => {
    const sw = el('i', { class: 'swatch' });
    sw.style.background = `rgb(${(byPart ? partRGB(n) : styleRGB(n)).join(',')})`;
    return el('span', {}, sw, n);
  }));
}

function refreshParts() {
  const bySource = $('group-by').value === 'source';
  const names = bySource ? S.asset.source_part_names : S.partNames;
  const key = bySource ? S.asset.source_part : S.part;
  const rows = [];
  names.forEach((name, k) => {
    const members = [];
    for (let i = 0; i < S.count; i++) if (key[i] === k) members.push(i);
    if (!members.length) return;
    const styles = new Set(members.map((i) => S.style[i]));
    const current = styles.size === 1 ? S.styleNames[[...styles][0]] : '';
    const select = el('select', { 'aria-label': `style of ${name}`, 'data-part': name, 'data-group': bySource ? 'source' : 'part' });
    options(select, styleChoices(), current, current ? [] : ['']);
    if (!current) select.options[0].text = '(mixed)';
    select.addEventListener('change', () => {
      if (select.value) edit(() => members.forEach((i) => { S.style[i] = styleIndex(select.value); }));
    });
    const sw = el('i', { class: 'swatch' });
    const labels = [...new Set(members.map((i) => S.partNames[S.part[i]]))];
    const byStyle = $('color-by').value === 'style';
    sw.style.background = `rgb(${(byStyle || bySource ? styleRGB(current || S.styleNames[S.style[members[0]]]) : partRGB(name)).join(',')})`;
    rows.push(el('div', { class: 'part-row' }, sw,
      el('span', { text: `${name} (${members.length})` + (bySource ? ` → ${labels.join(', ')}` : '') }), select));
  });
  $('parts').replaceChildren(...rows);
}

function refreshPickers() {
  const style = $('paint-style').value, part = $('paint-part').value;
  options($('paint-style'), styleChoices(), style || S.styleNames[0]);
  options($('paint-part'), partChoices(), part || KEEP, [KEEP]);
}

function refreshAll() {
  recolor();
  refreshParts();
  refreshPickers();
  $('undo').disabled = !S.history.length;
  $('save').textContent = S.dirty ? 'Save to recipe •' : 'Save to recipe';
}

// ------------------------------------------------------------------ editing

function styleIndex(name) {
  let i = S.styleNames.indexOf(name);
  if (i < 0) { S.styleNames.push(name); i = S.styleNames.length - 1; }
  return i;
}

function partIndex(name) {
  let i = S.partNames.indexOf(name);
  if (i < 0) { S.partNames.push(name); i = S.partNames.length - 1; }
  return i;
}

function snapshot() {
  S.history.push([S.part.slice(), S.style.slice(), [...S.partNames], [...S.styleNames]]);
  if (S.history.length > 100) S.history.shift();
}

// Run a change of S.part / S.style as one undoable edit, then redraw and (live) detailize.
async function edit(change, { record = true } = {}) {
  if (record) snapshot();
  change();
  S.dirty = true;
  S.lastEditAt = performance.now();
  if ($('live').checked) detailize('edit');  // its request leaves first; a newer one supersedes it
  refreshAll();
  await refreshPalette().catch(fail);
  refreshAll();
}

function paintVoxels(indices) {
  const style = styleIndex($('paint-style').value);
  const partName = $('paint-part').value;
  const part = partName && partName !== KEEP ? partIndex(partName) : -1;
  let changed = false;
  for (const i of indices) {
    if (S.style[i] !== style || (part >= 0 && S.part[i] !== part)) changed = true;
    S.style[i] = style;
    if (part >= 0) S.part[i] = part;
  }
  return changed;
}

function brushCells(i) {
  const size = Number($('brush-size').value);
  if (size === 1) return [i];
  const [x, y, z] = grid.cell(i), out = [];
  for (let dx = -1; dx <= 1; dx++) for (let dy = -1; dy <= 1; dy++) for (let dz = -1; dz <= 1; dz++) {
    const j = grid.at(x + dx, y + dy, z + dz);
    if (j >= 0) out.push(j);
  }
  return out;
}

let stroke = null;
$('coarse').addEventListener('pointerdown', (ev) => {
  if (S.tool !== 'brush' || ev.button !== 0 || !S.asset) return;
  const i = grid.pick(ev);
  if (i < 0) return;
  snapshot();
  stroke = { changed: paintVoxels(brushCells(i)) };
  recolor();
  $('coarse').setPointerCapture(ev.pointerId);
});
$('coarse').addEventListener('pointermove', (ev) => {
  if (S.tool !== 'brush' || !S.asset) return;
  const i = grid.pick(ev);
  grid.showHover(i, Number($('brush-size').value));
  if (stroke && i >= 0 && paintVoxels(brushCells(i))) { stroke.changed = true; recolor(); }
});
$('coarse').addEventListener('pointerup', () => {
  if (!stroke) return;
  const changed = stroke.changed;
  stroke = null;
  if (changed) edit(() => {}, { record: false });
  else S.history.pop();
});

function regionBounds() {
  const [X, Y, Z] = S.asset.shape;
  const v = (id, max) => Math.max(0, Math.min(max - 1, Math.round(Number($(id).value) || 0)));
  const lo = [v('x0', X), v('y0', Y), v('z0', Z)], hi = [v('x1', X), v('y1', Y), v('z1', Z)];
  return [lo.map((a, k) => Math.min(a, hi[k])), hi.map((b, k) => Math.max(b, lo[k]))];
}

function showRegion() {
  if (S.tool === 'region' && S.asset) grid.showRegion(...regionBounds());
  else grid.showRegion(null);
}

for (const id of ['x0', 'x1', 'y0', 'y1', 'z0', 'z1']) $(id).addEventListener('input', showRegion);
$('apply-region').addEventListener('click', () => {
  const [lo, hi] = regionBounds();
  const inside = [];
  for (let i = 0; i < S.count; i++) {
    const c = grid.cell(i);
    if (c.every((v, k) => v >= lo[k] && v <= hi[k])) inside.push(i);
  }
  edit(() => paintVoxels(inside));
});

function setTool(tool) {
  S.tool = tool;
  for (const t of ['orbit', 'brush', 'region']) $(`tool-${t}`).classList.toggle('active', t === tool);
  $('brush-opts').hidden = tool !== 'brush';
  $('region-opts').hidden = tool !== 'region';
  coarse.controls.mouseButtons.LEFT = tool === 'brush' ? null : THREE.MOUSE.ROTATE;
  coarse.controls.mouseButtons.RIGHT = tool === 'brush' ? THREE.MOUSE.ROTATE : THREE.MOUSE.PAN;
  grid.showHover(-1);
  showRegion();
}

// ------------------------------------------------------------------ detailize and show the mesh

function hex(buffer) {
  return [...new Uint8Array(buffer)].map((b) => b.toString(16).padStart(2, '0')).join('');
}

function onlyLod0(scene) {
  scene.traverse((o) => {
    if (!o.isMesh) return;
    for (let p = o; p; p = p.parent) {
      if (!p.name) continue;
      const role = nodeRole(p.name);
      if (role.collision || role.lod > 0) { o.visible = false; break; }
    }
  });
  return scene;
}

async function showMesh(object, keepView) {
  fine.show(object, { keepView });
  if (!keepView) fine.frame();
}

async function detailize(trigger = 'button') {
  if (!S.asset) return;
  const seq = ++S.seq;
  const t0 = trigger === 'edit' && S.lastEditAt ? S.lastEditAt : performance.now();
  const name = S.asset.name;
  status('detailizing…');
  $('result-state').textContent = 'detailizing…';
  let job;
  try {
    job = await postJSON('/api/detailize', { asset: name, detailizer: $('detailizer').value, target: target() });
  } catch (err) { if (seq === S.seq) fail(err); return; }
  const timing = { trigger, detailizer: $('detailizer').value, asset: name,
    posted_ms: Math.round(performance.now() - t0) };
  let previewShown = false;
  let state = 'queued';
  for (;;) {
    let j;
    try { j = await getJSON(`/api/job?id=${job.job}&unless=${state}`); } catch (err) { if (seq === S.seq) fail(err); return; }
    state = j.state;
    if (seq !== S.seq) return;  // a newer request took over
    if (j.preview_url && !previewShown && (j.state === 'preview' || j.state === 'done')) {
      timing.seen_ms = Math.round(performance.now() - t0);
      const scene = await fine.loadGLB(j.preview_url);
      timing.loaded_ms = Math.round(performance.now() - t0);
      if (seq !== S.seq) return;
      await showMesh(scene, S.shownAsset === name);
      S.shownAsset = name;
      previewShown = true;
      await new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
      timing.preview_ms = Math.round(performance.now() - t0);
      timing.server_preview_s = j.preview_timings_s;
      $('result-state').textContent = `preview (1/${j.preview_factor} resolution, ${j.preview_triangles.toLocaleString('en')} triangles); building the exact GLB…`;
      status(`preview in ${(timing.preview_ms / 1000).toFixed(2)} s`, 'good');
    }
    if (j.state === 'done') {
      const bytes = await (await fetch(j.glb_url)).arrayBuffer();
      const sha256 = hex(await crypto.subtle.digest('SHA-256', bytes));
      const scene = await fine.parseGLB(bytes);
      if (seq !== S.seq) return;
      await showMesh(onlyLod0(scene), S.shownAsset === name && previewShown);
      S.shownAsset = name;
      timing.exact_ms = Math.round(performance.now() - t0);
      const e = j.entry || {}, m = e.mesh || {}, st = e.structure || {};
      $('result-state').textContent = `exact GLB (what decollage build writes)`;
      $('result-figures').textContent = [`${(m.triangles || 0).toLocaleString('en')} triangles`,
        st.strict_iou != null ? `Strict/Loose-IOU ${st.strict_iou.toFixed(3)}/${st.loose_iou.toFixed(3)}` : '',
        `${j.detailizer ? j.detailizer.name : ''}`, `${(timing.exact_ms / 1000).toFixed(2)} s`].filter(Boolean).join(' · ');
      $('result-hash').textContent = `sha256 ${sha256.slice(0, 16)}…`;
      $('result-hash').title = sha256;
      studio.result = { asset: name, sha256, server_sha256: j.glb_sha256, entry: e, job: j.id };
      studio.timings.push(timing);
      status(`detailized: preview ${(timing.preview_ms / 1000).toFixed(2)} s, exact GLB ${(timing.exact_ms / 1000).toFixed(2)} s`, 'good');
      return;
    }
    if (j.state === 'failed') { fail(new Error(j.error)); $('result-state').textContent = 'failed'; return; }
    if (j.state === 'superseded') return;
  }
}

// ------------------------------------------------------------------ loading and saving

async function loadVocab(name) {
  try {
    const v = await getJSON(`/api/detailizer?name=${encodeURIComponent(name)}&asset=${encodeURIComponent(S.asset.name)}`);
    S.vocab = { styles: v.style_names, parts: v.part_names, learned: v.learned };
  } catch (err) {
    S.vocab = { styles: null, parts: null, learned: false };
    fail(err);
  }
}

async function loadAsset(name) {
  status(`loading ${name}…`);
  S.asset = null;
  S.seq += 1;
  try {
    const data = await getJSON(`/api/asset?name=${encodeURIComponent(name)}`);
    S.asset = data;
    S.count = data.cells.length / 3;
    S.part = Int32Array.from(data.part);
    S.style = Int32Array.from(data.style);
    S.partNames = [...data.part_names];
    S.styleNames = [...data.style_names];
    S.palette = { ...data.palette };
    S.history = [];
    S.dirty = false;
    grid.set(data);
    $('grid-info').textContent = `${data.shape.join('×')}, ${S.count} voxels, ${data.voxel_size_m.toFixed(3)} m`;
    const [X, Y, Z] = data.shape;
    for (const [id, v] of [['x0', 0], ['y0', 0], ['z0', 0], ['x1', X - 1], ['y1', Y - 1], ['z1', Z - 1]]) $(id).value = v;
    $('detailizer').value = data.detailize.detailizer;
    await loadVocab(data.detailize.detailizer);
    await refreshPalette();
    $('live').checked = !S.vocab.learned;
    $('save').disabled = !data.savable;
    $('save-note').hidden = !data.save_note;
    $('save-note').textContent = data.save_note || '';
    $('warnings').replaceChildren(...data.warnings.map((w) => el('li', { text: w })));
    fine.show(null);
    S.shownAsset = null;
    $('result-state').textContent = 'press Detailize';
    $('result-figures').textContent = '';
    $('result-hash').textContent = '';
    refreshAll();
    coarse.frame();
    status(`${name}: ${data.rules.length} region rules`);
    studio.ready = true;
  } catch (err) {
    grid.mesh = null;
    coarse.show(null);
    fail(err);
    studio.ready = true;
  }
}

async function save() {
  if (!S.asset) return;
  status('saving…');
  try {
    const r = await postJSON('/api/save', { asset: S.asset.name, detailizer: $('detailizer').value, target: target(),
      recipe_sha256: S.asset.recipe_sha256 });
    studio.saved = r;
    $('diff').hidden = !r.changed;
    $('diff').textContent = r.diff || '';
    const keep = { part: S.part, style: S.style, partNames: S.partNames, styleNames: S.styleNames };
    if (r.changed) {
      const data = await getJSON(`/api/asset?name=${encodeURIComponent(S.asset.name)}`);
      S.asset = data;  // the new rules and file hash; the painted labels stay as they are
      Object.assign(S, keep);
    }
    S.dirty = false;
    refreshAll();
    status(r.changed ? `saved ${r.edits.length} edit(s) to ${S.session.recipe.split('/').pop()}` : 'nothing to save', 'good');
  } catch (err) { fail(err); }
}

async function main() {
  S.session = await getJSON('/api/session');
  $('recipe').textContent = S.session.recipe;
  options($('asset'), [], null);
  $('asset').replaceChildren(...S.session.assets.map((a) => el('option', {
    value: a.name, text: a.name + (a.variant ? ' (variant)' : '') + (a.script ? ' (script)' : ''),
  })));
  options($('detailizer'), S.session.detailizers, null);
  $('asset').value = S.session.initial;
  $('asset').addEventListener('change', () => loadAsset($('asset').value));
  $('detailizer').addEventListener('change', async () => {
    await loadVocab($('detailizer').value);
    await refreshPalette().catch(fail);
    $('live').checked = !S.vocab.learned;
    S.dirty = true;
    refreshAll();
  });
  $('detailize').addEventListener('click', () => detailize('button'));
  $('save').addEventListener('click', save);
  $('undo').addEventListener('click', () => {
    const last = S.history.pop();
    if (!last) return;
    [S.part, S.style, S.partNames, S.styleNames] = last;
    edit(() => {}, { record: false });
  });
  $('reset').addEventListener('click', () => edit(() => {
    S.part = Int32Array.from(S.asset.part);
    S.style = Int32Array.from(S.asset.style);
    S.partNames = [...S.asset.part_names];
    S.styleNames = [...S.asset.style_names];
  }));
  $('color-by').addEventListener('change', refreshAll);
  $('group-by').addEventListener('change', refreshParts);
  for (const t of ['orbit', 'brush', 'region']) $(`tool-${t}`).addEventListener('click', () => setTool(t));
  $('add-style').addEventListener('click', async () => {
    const name = $('new-name').value.trim();
    if (!/^[A-Za-z0-9][A-Za-z0-9_.-]*$/.test(name)) return status('a name is letters, digits, _ . -', 'bad');
    if (!S.extraStyles.includes(name)) S.extraStyles.push(name);
    await refreshPalette().catch(fail);
    refreshAll();
    $('paint-style').value = name;
  });
  $('add-part').addEventListener('click', () => {
    const name = $('new-name').value.trim();
    if (!/^[A-Za-z0-9][A-Za-z0-9_.-]*$/.test(name)) return status('a name is letters, digits, _ . -', 'bad');
    if (!S.extraParts.includes(name)) S.extraParts.push(name);
    refreshAll();
    $('paint-part').value = name;
  });
  // Orbit both views together: the fine view follows the coarse one's direction (and back).
  let syncing = false;
  const follow = (from, to) => () => {
    if (syncing || !$('sync').checked) return;
    syncing = true;
    const dir = from.camera.position.clone().sub(from.controls.target).normalize();
    const dist = to.camera.position.distanceTo(to.controls.target);
    to.camera.position.copy(to.controls.target).addScaledVector(dir, dist);
    to.controls.update();
    syncing = false;
  };
  coarse.controls.addEventListener('change', follow(coarse, fine));
  fine.controls.addEventListener('change', follow(fine, coarse));
  await loadAsset(S.session.initial);
}

main().catch(fail);
