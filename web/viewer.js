// hmap view: the map served by `hmap view` (src/hmap/serve), drawn with Debian's three.js.
// The HVoxels arrive as 32-byte box records per view tile and level of detail
// (src/hmap/view/map_scene.hpp); tiles are asked for when they come into view, coarser the
// farther they are. window.hmapViewer is what the browser test (tests/view) drives.

import * as THREE from '/three/build/three.module.js';
import { OrbitControls } from '/three/examples/jsm/controls/OrbitControls.js';

const moduleTop = performance.now();  // three.js fetched, compiled and evaluated

const BOX_BYTES = 32;
const MAX_REQUESTS = 4;          // tile requests in flight (but for the first view's: startRenderer)
const BOX_BUDGET = 2000000;      // boxes drawn at most: coarser levels beyond
const CELL_PIXELS = 3;           // a cell smaller than this on screen: the next coarser level

const $ = (id) => document.getElementById(id);
const status = (text) => { $('status').textContent = text; };

// Starting WebGL blocks the page for seconds with software GL (1.2-3.5 s with SwiftShader on the
// test machine): the map's summary is asked for first, and the renderer made only once the
// first view's tiles are asked for, all at once (the browser fetches them meanwhile).
let firstMap = fetch('/api/map');
firstMap.catch(() => {});  // handled where it is awaited (loadMap)

const view = $('view');  // the canvas fills it: pointer events and sizes are taken from it
let renderer = null;
let rendererUp = null;
function startRenderer() {
  renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(view.clientWidth, view.clientHeight);
  renderer.setClearColor(0x1d2024);
  renderer.localClippingEnabled = true;
  view.appendChild(renderer.domElement);
  rendererUp = performance.now();
}

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(50, view.clientWidth / view.clientHeight, 0.05, 5000);
camera.up.set(0, 0, 1);  // the map's z is up
const controls = new OrbitControls(camera, view);
controls.screenSpacePanning = true;
scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 0.75));
const sun = new THREE.DirectionalLight(0xffffff, 0.55);
sun.position.set(0.4, 0.25, 1.0);
scene.add(sun);

// Everything above the slider's height is cut away (to look under a ceiling).
const cut = new THREE.Plane(new THREE.Vector3(0, 0, -1), 1e6);
// ?flat=1: the colours unshaded, exactly as encoded (the browser test reads them back).
const flat = new URLSearchParams(location.search).get('flat') === '1';
const boxMaterial = new (flat ? THREE.MeshBasicMaterial : THREE.MeshLambertMaterial)({ vertexColors: THREE.VertexColors, clippingPlanes: [cut] });
const layers = {
  hvoxels: new THREE.Group(), grid: new THREE.Group(), ground: new THREE.Group(), trajectory: new THREE.Group(),
};
for (const group of Object.values(layers)) scene.add(group);

let info = null;           // /api/map
let colourMode = 'height';
const tiles = new Map();   // "a,b" -> { a, b, n, centre, box, meshes: [], pending: Set, shown }
const queue = [];
let inFlight = 0;
let maxRequests = Infinity;  // until the renderer is up
let dirty = true;
let frames = 0;
const highlight = new THREE.LineSegments(new THREE.EdgesGeometry(new THREE.BoxBufferGeometry(1, 1, 1)),
  new THREE.LineBasicMaterial({ color: 0xffffff }));
highlight.visible = false;
scene.add(highlight);

function densityColour(d, out, k) {
  // ρ in [0, 1] (or a PVOX voxel's probability in [0.5, 1]): dark violet (sparse, unsure) to
  // bright yellow (dense, sure).
  const t = Math.min(1, Math.max(0, info.format === 'pvox' ? 2 * d - 1 : d));
  out[k] = 60 + 195 * t; out[k + 1] = 20 + 210 * t; out[k + 2] = 110 - 80 * t;
}

// Where the opening's time goes (the browser test's measurements): ms spent building tile meshes
// from their bytes, and in renderer.render (SwiftShader's GL work lands there).
const spent = { meshMs: 0, meshes: 0, renderMs: 0, renders: 0, lastMeshAt: 0, updateMs: 0, updates: 0 };

function makeTileMesh(buffer) {
  const t0 = performance.now();
  try { return buildTileMesh(buffer); } finally { spent.meshMs += performance.now() - t0; ++spent.meshes; }
}

function buildTileMesh(buffer) {
  const n = buffer.byteLength / BOX_BYTES;
  const f = new Float32Array(buffer);
  const u = new Uint8Array(buffer);
  const geometry = new THREE.BoxBufferGeometry(1, 1, 1);
  const mesh = new THREE.InstancedMesh(geometry, boxMaterial, n);
  const m = mesh.instanceMatrix.array;
  const height = new Uint8Array(3 * n);
  const density = new Uint8Array(3 * n);
  for (let i = 0; i < n; ++i) {
    const r = 8 * i;
    // Column-major 4x4: scale by the size, move to the centre.
    m.set([f[r + 3], 0, 0, 0, 0, f[r + 4], 0, 0, 0, 0, f[r + 5], 0, f[r], f[r + 1], f[r + 2], 1], 16 * i);
    height.set(u.subarray(32 * i + 28, 32 * i + 31), 3 * i);
    densityColour(f[r + 6], density, 3 * i);
  }
  mesh.instanceMatrix.needsUpdate = true;
  // One colour per box: an instanced "color" attribute read by the vertex colours.
  mesh.userData = { boxes: f, height: new THREE.InstancedBufferAttribute(height, 3, true),
    density: new THREE.InstancedBufferAttribute(density, 3, true) };
  geometry.setAttribute('color', mesh.userData[colourMode]);
  mesh.frustumCulled = false;  // the unit box's bounds are not the tile's; tiles are culled here
  return mesh;
}

function tileLevel(t) {
  const cell = info.cell_size;
  const d = Math.max(camera.position.distanceTo(t.centre), 1e-3);
  const pixelsPerMetre = view.clientHeight / (2 * Math.tan(((camera.fov / 2) * Math.PI / 180)) * d);
  let level = 0;
  while (level < info.levels - 1 && cell * (1 << level) * pixelsPerMetre < CELL_PIXELS) ++level;
  return level;
}

const frustum = new THREE.Frustum();
const projScreen = new THREE.Matrix4();

// Which tiles to show at which level; asks for the ones not loaded yet, nearest first.
function updateTiles() {
  const t0 = performance.now();
  try { chooseTiles(); } finally { spent.updateMs += performance.now() - t0; ++spent.updates; }
}

function chooseTiles() {
  if (!info) return;
  camera.updateMatrixWorld();
  projScreen.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
  frustum.setFromMatrix(projScreen);
  const wanted = [];
  let budget = 0;
  for (const t of tiles.values()) {
    t.want = frustum.intersectsBox(t.box) ? tileLevel(t) : -1;
    if (t.want >= 0) { wanted.push(t); budget += t.n / (1 << (2 * t.want)); }
  }
  // Over the budget: coarsen the farthest first.
  wanted.sort((p, q) => camera.position.distanceTo(p.centre) - camera.position.distanceTo(q.centre));
  for (let k = wanted.length - 1; k >= 0 && budget > BOX_BUDGET; --k) {
    const t = wanted[k];
    while (t.want < info.levels - 1 && budget > BOX_BUDGET) {
      budget -= t.n / (1 << (2 * t.want)) - t.n / (1 << (2 * (t.want + 1)));
      ++t.want;
    }
  }
  let drawn = 0;
  for (const t of tiles.values()) {
    // Show the wanted level when loaded, else the nearest loaded one meanwhile.
    let shown = -1;
    if (t.want >= 0) {
      if (t.meshes[t.want]) shown = t.want;
      else {
        if (!t.pending.has(t.want) && !t.failed.has(t.want)) { t.pending.add(t.want); queue.push([t, t.want]); }
        for (let l = 0; l < info.levels; ++l) if (t.meshes[l] && (shown < 0 || Math.abs(l - t.want) < Math.abs(shown - t.want))) shown = l;
      }
    }
    t.meshes.forEach((mesh, l) => { if (mesh) mesh.visible = l === shown; });
    if (shown >= 0) drawn += t.meshes[shown].count;
  }
  queue.sort((p, q) => camera.position.distanceTo(p[0].centre) - camera.position.distanceTo(q[0].centre));
  pump();
  if (!queue.length && !inFlight && stale.length) dropStale();
  api.boxesDrawn = drawn;
  status(`${info.hvoxels} ${info.format === 'pvox' ? 'voxels' : 'HVoxels'}, ${tiles.size} tiles; ${drawn} boxes drawn` + (queue.length + inFlight ? `, loading ${queue.length + inFlight}` : ''));
  dirty = true;
}

function pump() {
  while (inFlight < maxRequests && queue.length) {
    const [t, level] = queue.shift();
    ++inFlight;
    fetch(`/api/tile?a=${t.a}&b=${t.b}&level=${level}`)
      .then((r) => { if (!r.ok) throw new Error(`tile ${t.a},${t.b}: HTTP ${r.status}`); return r.arrayBuffer(); })
      .then((buffer) => {
        if (t.dropped) return;  // a tile of a map replaced meanwhile
        const mesh = makeTileMesh(buffer);
        mesh.visible = false;
        t.meshes[level] = mesh;
        spent.lastMeshAt = performance.now();
        layers.hvoxels.add(mesh);
      })
      .catch((e) => { t.failed.add(level); console.error(e.message); })
      .finally(() => { t.pending.delete(level); --inFlight; scheduleUpdate(); });
  }
}

// Tiles are chosen again once for the answers that came together, not once per answer: the 196
// of the first view of a million HVoxels arrive at once, and choosing took 1.3 ms each time.
let updateScheduled = false;
function scheduleUpdate() {
  if (updateScheduled) return;
  updateScheduled = true;
  setTimeout(() => {
    updateScheduled = false;
    updateTiles();
    if (!queue.length && !inFlight) settle();
  }, 0);
}

let stale = [];  // meshes of the map before, shown until this one's tiles are in
function disposeMesh(mesh) { layers.hvoxels.remove(mesh); mesh.geometry.dispose(); }
function dropStale() { for (const mesh of stale) disposeMesh(mesh); stale = []; dirty = true; }

let settleWaiters = [];
function settle() { const w = settleWaiters; settleWaiters = []; for (const f of w) f(); }
/// Resolves once every tile asked for is loaded and drawn.
function settled() {
  return new Promise((resolve) => {
    const done = () => { renderNow(); resolve(); };
    if (!queue.length && !inFlight) done(); else settleWaiters.push(done);
  });
}

function addGrid(g, cells) {
  const rgba = new Uint8Array(4 * g.width * g.height);
  for (let k = 0; k < cells.length; ++k) {
    const c = cells[k];
    if (c === 255) continue;  // unknown: transparent
    const v = Math.round(255 * (1 - c / 100));  // map_server's convention: free white, occupied black
    rgba.set([v, v, v, 200], 4 * k);
  }
  const texture = new THREE.DataTexture(rgba, g.width, g.height, THREE.RGBAFormat);
  texture.magFilter = THREE.NearestFilter;
  texture.minFilter = THREE.NearestFilter;
  texture.needsUpdate = true;
  const w = g.width * g.resolution; const h = g.height * g.resolution;
  const plane = new THREE.Mesh(new THREE.PlaneBufferGeometry(w, h),
    new THREE.MeshBasicMaterial({ map: texture, transparent: true, side: THREE.DoubleSide, depthWrite: false }));
  // Row 0 of the image is the southernmost (v = 0 at the plane's bottom edge).
  plane.position.set(g.origin[0] + w / 2, g.origin[1] + h / 2, info.z_range[0] - 0.05);
  layers.grid.add(plane);
}

function addGround(patches) {
  if (!patches.length) return;
  const mesh = new THREE.InstancedMesh(new THREE.BoxBufferGeometry(1, 1, 0.02),
    new THREE.MeshLambertMaterial({ color: 0x44aa55, transparent: true, opacity: 0.55, clippingPlanes: [cut] }), patches.length);
  const q = new THREE.Quaternion(); const s = new THREE.Vector3(); const p = new THREE.Vector3(); const m = new THREE.Matrix4();
  patches.forEach(([x, y, z, nx, ny, nz, half], i) => {
    q.setFromUnitVectors(new THREE.Vector3(0, 0, 1), new THREE.Vector3(nx, ny, nz));
    m.compose(p.set(x, y, z), q, s.set(2 * half, 2 * half, 1));
    mesh.setMatrixAt(i, m);
  });
  mesh.frustumCulled = false;
  layers.ground.add(mesh);
}

function addTrajectory(points) {
  api.trajectoryDrawn = points.length < 2 ? 0 : points.length;  // poses on the line drawn
  if (points.length < 2) return;
  const geometry = new THREE.BufferGeometry().setFromPoints(points.map(([x, y, z]) => new THREE.Vector3(x, y, z)));
  layers.trajectory.add(new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0xff40ff, clippingPlanes: [cut] })));
}

function setView(kind) {
  const b = info.bounds;
  const min = b ? new THREE.Vector3(...b.min) : new THREE.Vector3(0, 0, 0);
  const max = b ? new THREE.Vector3(...b.max) : new THREE.Vector3(1, 1, 1);
  const centre = min.clone().add(max).multiplyScalar(0.5);
  const size = Math.max(max.x - min.x, max.y - min.y, 1);
  controls.target.copy(centre);
  if (kind === 'top') {
    // Straight down, x to the right, y up the screen; the whole map in view.
    const aspect = view.clientWidth / view.clientHeight;
    const fit = Math.max(max.y - min.y, (max.x - min.x) / aspect, 1) * 1.1;
    camera.up.set(0, 1, 0);
    camera.position.set(centre.x, centre.y, max.z + fit / (2 * Math.tan(((camera.fov / 2) * Math.PI / 180))));
    camera.lookAt(centre);
    camera.up.set(0, 0, 1);  // the controls' up; not updated here, which would tilt the view off the vertical
  } else {
    camera.position.set(centre.x - 0.6 * size, centre.y - 0.9 * size, centre.z + 0.8 * size);
    controls.update();
  }
  camera.far = 20 * size + 100;
  camera.near = Math.max(0.02, size / 5000);
  camera.updateProjectionMatrix();
  updateTiles();
}

function renderNow() {
  if (!renderer) return;
  const t0 = performance.now();
  renderer.render(scene, camera);
  spent.renderMs += performance.now() - t0; ++spent.renders;
  ++frames; dirty = false;
}

function loop() {
  requestAnimationFrame(loop);
  if (dirty) renderNow();
}

function setLayer(name, on) {
  layers[name].visible = on;
  $(`layer-${name}`).checked = on;
  dirty = true;
}

function setCut(z) {
  cut.constant = z;  // keeps z <= constant
  $('cut-value').textContent = z >= info.z_range[1] ? '(off)' : `${z.toFixed(2)} m`;
  dirty = true;
}

function setColour(mode) {
  colourMode = mode;
  for (const t of tiles.values()) for (const mesh of t.meshes) if (mesh) mesh.geometry.setAttribute('color', mesh.userData[mode]);
  dirty = true;
}

// Clicking a box: the column of its cell (GET /api/column).
const raycaster = new THREE.Raycaster();
async function pick(clientX, clientY) {
  const rect = view.getBoundingClientRect();
  const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const visible = layers.hvoxels.visible ? layers.hvoxels.children.filter((m) => m.visible) : [];
  const hit = raycaster.intersectObjects(visible, false).find((h) => h.point.z <= cut.constant);
  let point = null;
  if (hit) point = hit.point.clone().addScaledVector(raycaster.ray.direction, 1e-3);  // just inside the box
  else {
    const floor = new THREE.Plane(new THREE.Vector3(0, 0, 1), -info.z_range[0]);
    point = raycaster.ray.intersectPlane(floor, new THREE.Vector3());
  }
  if (!point) return null;
  return showColumn(point.x, point.y);
}

async function showColumn(x, y) {
  const r = await fetch(`/api/column?x=${x}&y=${y}`);
  if (!r.ok) { console.error(`column: HTTP ${r.status}`); return null; }
  const c = await r.json();
  const fmt = (v, d) => (v === null ? '–' : v.toFixed(d));
  const rows = c.hvoxels.slice().reverse().map((h) => `<tr><td>${fmt(h.z_min, 2)}</td><td>${fmt(h.z_max, 2)}</td>` +
    `<td>${fmt(h.count, 1)}</td><td>${fmt(h.density, 2)}</td><td>${fmt(h.occupancy, 2)}</td><td>${h.role ?? '–'}</td></tr>`);
  const panel = $('column');
  panel.hidden = false;
  panel.innerHTML = `<b>cell (${c.cell[0]}, ${c.cell[1]})</b> at (${c.centre[0].toFixed(2)}, ${c.centre[1].toFixed(2)}) m<br>` +
    `ground ${fmt(c.ground_z, 2)} m · 2D grid p ${fmt(c.grid_probability, 2)}<br>` +
    (rows.length ? `<table><tr><th>z_min</th><th>z_max</th><th>count</th><th>ρ</th><th>p</th><th>role</th></tr>${rows.join('')}</table>`
      : 'no HVoxel');
  panel.dataset.column = JSON.stringify(c);
  const s = info.cell_size;
  if (c.hvoxels.length) {
    const lo = c.hvoxels[0].z_min; const hi = c.hvoxels[c.hvoxels.length - 1].z_max;
    highlight.position.set(c.centre[0], c.centre[1], (lo + hi) / 2);
    highlight.scale.set(s * 1.05, s * 1.05, Math.max(hi - lo, s / 10) * 1.02);
    highlight.visible = true;
  } else highlight.visible = false;
  dirty = true;
  api.lastColumn = c;
  return c;
}

let down = null;
view.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
view.addEventListener('pointerup', (e) => {
  if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4 && e.button === 0) pick(e.clientX, e.clientY);
  down = null;
});

let tileTimer = null;
controls.addEventListener('change', () => {
  dirty = true;
  clearTimeout(tileTimer);
  tileTimer = setTimeout(updateTiles, 120);
});
window.addEventListener('resize', () => {
  camera.aspect = view.clientWidth / view.clientHeight;
  camera.updateProjectionMatrix();
  if (renderer) renderer.setSize(view.clientWidth, view.clientHeight);
  updateTiles();
});
for (const name of Object.keys(layers)) $(`layer-${name}`).addEventListener('change', (e) => setLayer(name, e.target.checked));
$('colour').addEventListener('change', (e) => setColour(e.target.value));
$('cut').addEventListener('input', (e) => {
  const [lo, hi] = info.z_range;
  setCut(lo + (hi - lo) * (e.target.value / 1000) + (e.target.value === '1000' ? 1e6 : 0));
});

/// Frames per second while the camera turns around the map for `ms` milliseconds.
async function measureFps(ms) {
  const start = performance.now();
  const f0 = frames;
  const target = controls.target.clone();
  const offset = camera.position.clone().sub(target);
  await new Promise((resolve) => {
    const step = () => {
      const t = performance.now() - start;
      offset.applyAxisAngle(new THREE.Vector3(0, 0, 1), 0.02);
      camera.position.copy(target).add(offset);
      camera.lookAt(target);
      renderNow();
      if (t < ms) requestAnimationFrame(step); else resolve();
    };
    requestAnimationFrame(step);
  });
  return (frames - f0) / ((performance.now() - start) / 1000);
}

const api = {
  boxesDrawn: 0, trajectoryDrawn: 0, lastColumn: null, info: null, version: 0, spent,
  setLayer, setView, setCut, setColour, showColumn, pick, settled, renderNow, measureFps,
  /// A live view still catching up: a map being fetched or tiles in flight.
  busy() { return reloading || queue.length + inFlight > 0; },
  /// Boxes on screen: this map's and those of the one before still shown.
  boxesOnScreen() { return layers.hvoxels.children.reduce((n, m) => n + (m.visible ? m.count : 0), 0); },
  /// The colour of each pixel, read back from the canvas: [width, height, RGBA bytes, bottom row first].
  pixels() {
    renderNow();
    const gl = renderer.getContext();
    const w = gl.drawingBufferWidth; const h = gl.drawingBufferHeight;
    const out = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, out);
    return [w, h, out];
  },
  /// World (x, y, z) to CSS pixels of the page.
  toScreen(x, y, z) {
    const p = new THREE.Vector3(x, y, z).project(camera);
    const rect = view.getBoundingClientRect();
    return [rect.left + (p.x + 1) / 2 * rect.width, rect.top + (1 - p.y) / 2 * rect.height];
  },
};
window.hmapViewer = api;

/// Fetches the map's description and its layers; drops what an earlier map had drawn.
async function loadMap() {
  // The map comes with its version (a map replaced while this one loads is loaded again at its
  // event) and its progress: a page opened during or after a live run shows it at once.
  const r = await (firstMap ?? fetch('/api/map'));
  firstMap = null;
  if (!r.ok) throw new Error(`map: HTTP ${r.status}`);
  const fresh = await r.json();
  const version = fresh.version;
  if (fresh.progress && version >= latestEvent) $('progress').textContent = fresh.progress;
  // The boxes on screen stay until the new map's are in (a live view would blink at every map);
  // answers still coming for the old tiles are dropped.
  for (const t of tiles.values()) {
    t.dropped = true;
    for (const mesh of t.meshes) if (mesh) { if (mesh.visible) stale.push(mesh); else disposeMesh(mesh); }
  }
  tiles.clear();
  queue.length = 0;
  for (const name of ['grid', 'ground', 'trajectory']) layers[name].remove(...layers[name].children);
  info = fresh;
  api.info = info;
  api.version = version;
  const edge = info.tile_cells * info.cell_size;
  const zLo = info.z_range[0]; const zHi = info.z_range[1];
  for (const [a, b, n] of info.tiles) {
    const box = new THREE.Box3(new THREE.Vector3(a * edge, b * edge, zLo), new THREE.Vector3((a + 1) * edge, (b + 1) * edge, zHi));
    tiles.set(`${a},${b}`, { a, b, n, box, centre: box.getCenter(new THREE.Vector3()), meshes: [], pending: new Set(), failed: new Set(), want: -1 });
  }
  if (info.grid) {
    const g = await fetch('/api/grid');
    if (!g.ok) throw new Error(`grid: HTTP ${g.status}`);
    addGrid(info.grid, new Uint8Array(await g.arrayBuffer()));
  }
  addGround(info.ground);
  addTrajectory(info.trajectory);
}

async function start() {
  api.timing = { three: moduleTop, module: performance.now() };
  await loadMap();
  setCut(1e6);
  if (info.format === 'pvox') {
    // Voxels of a PVOX map carry their occupancy probability where HVoxels carry ρ.
    $('colour').value = 'density';
    $('colour').options[1].textContent = 'by probability';
    colourMode = 'density';
  }
  api.timing.info = performance.now();
  setView(new URLSearchParams(location.search).get('view') === 'top' ? 'top' : 'oblique');  // asks for the tiles
  startRenderer();
  api.timing.webgl = rendererUp;
  maxRequests = MAX_REQUESTS;
  await settled();
  api.timing.drawn = performance.now();
  loop();
  listen();
}

// A live view (hmap map --view): a new map at each event; the camera stays where the user put it.
let reloading = false;
let latestEvent = 0;  // the version of the last event: the map and progress the server is at
function listen() {
  const events = new EventSource('/api/events');
  const reload = async () => {
    if (reloading || latestEvent === api.version) return;
    reloading = true;
    try {
      const fitted = !info.bounds;  // the first HVoxels of a live map: frame them
      await loadMap();
      if (fitted) setView('oblique'); else updateTiles();
    } catch (err) {
      console.error(`live view: ${err.message}`);
    } finally {
      reloading = false;
    }
    reload();  // an event that came while loading
  };
  events.onmessage = (e) => {
    const s = JSON.parse(e.data);
    if (s.progress) $('progress').textContent = s.progress;
    latestEvent = s.version;
    reload();
  };
}

api.ready = start().catch((e) => { console.error(`hmap view: ${e.message}`); status(`error: ${e.message}`); throw e; });
