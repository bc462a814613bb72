// Drives headless Chromium over the DevTools protocol (Node's own WebSocket: no npm package) on a
// running `hmap view`, or on `hmap slam/map --view` it starts (--live), for
// tests/browser/browser_test.cpp. Prints one JSON object: what the page showed and did; the C++
// test judges it against the map. {"skip": why} when Chromium cannot start.
//
//   node --experimental-websocket browser_check.mjs CHROMIUM URL OUT_DIR POINTS_JSON
//   node --experimental-websocket browser_check.mjs CHROMIUM --live OUT_DIR HMAP ARGS...
//
// POINTS_JSON: [[x, y, z], ...] map points on top of boxes, seen from straight above with unshaded
// colours; the pixel under each is read back with every layer on and with the HVoxels hidden, and
// the first is clicked for its column. [] (a measurement): the page as a user opens it, timed.
// --live: once Chromium is up, runs `HMAP ARGS...` (hmap map or slam with --view), opens the URL it
// prints and samples what the page shows until the run is done and drawn; then SIGTERM to hmap.

import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, readdirSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

const [chromium, urlArg, outDir, ...rest] = process.argv.slice(2);
const live = urlArg === '--live';
const points = live ? [] : JSON.parse(rest[0]);
const profile = mkdtempSync(join(tmpdir(), 'hmap-chromium-'));
const started = Date.now();
let browser = null;
let hmap = null;  // --live: the hmap run
let hmapOutput = '';

/// CPU seconds (user + system) of Chromium's processes so far: the browser and its descendants.
function chromiumCpuSeconds() {
  if (!browser) return 0;
  const stats = [];
  for (const pid of readdirSync('/proc')) {
    if (!/^\d+$/.test(pid)) continue;
    try {
      const text = readFileSync(`/proc/${pid}/stat`, 'utf8');
      const f = text.slice(text.lastIndexOf(')') + 2).split(' ');  // fields from the state on
      stats.push({ pid: Number(pid), ppid: Number(f[1]), ticks: Number(f[11]) + Number(f[12]) });
    } catch { /* gone meanwhile */ }
  }
  const tree = new Set([browser.pid]);
  for (let grew = true; grew;) {
    grew = false;
    for (const s of stats) if (!tree.has(s.pid) && tree.has(s.ppid)) { tree.add(s.pid); grew = true; }
  }
  return stats.filter((s) => tree.has(s.pid)).reduce((sum, s) => sum + s.ticks, 0) / 100;  // USER_HZ
}

function finish(result, code = 0) {
  if (browser) browser.kill('SIGKILL');
  if (hmap && hmap.exitCode === null) { hmap.kill('SIGKILL'); result.hmap_output = hmapOutput; }
  try { rmSync(profile, { recursive: true, force: true }); } catch { /* a profile left in /tmp */ }
  process.stdout.write(JSON.stringify(result) + '\n');
  process.exit(code);
}
const limitS = live ? 80 : 60;  // the live test simulates first and may follow the run twice: within ctest's 240 s
setTimeout(() => finish({ error: `timed out after ${limitS} s` }, 1), limitS * 1000).unref();

// Chromium with software GL (SwiftShader through ANGLE), its DevTools on a free port.
browser = spawn(chromium, ['--headless=new', '--no-sandbox', '--disable-dev-shm-usage', '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--window-size=800,600', '--hide-scrollbars',
  '--no-first-run', '--no-default-browser-check', `--user-data-dir=${profile}`, '--remote-debugging-port=0',
  'about:blank'], { stdio: ['ignore', 'ignore', 'pipe'] });
browser.on('error', (e) => finish({ skip: `chromium did not start: ${e.message}` }));
let stderr = '';
const wsUrl = await new Promise((resolve) => {
  browser.stderr.on('data', (d) => {
    stderr += d;
    const m = stderr.match(/DevTools listening on (ws:\/\/\S+)/);
    if (m) resolve(m[1]);
  });
  browser.on('exit', (code) => finish({ skip: `chromium exited (${code}) before its DevTools opened: ${stderr.slice(-400)}` }));
});
const devtoolsPort = new URL(wsUrl).port;
const targets = await (await fetch(`http://127.0.0.1:${devtoolsPort}/json/list`)).json();
const page = targets.find((t) => t.type === 'page');
if (!page) finish({ skip: 'chromium opened no page' });

const ws = new WebSocket(page.webSocketDebuggerUrl);
await new Promise((resolve, reject) => { ws.onopen = resolve; ws.onerror = reject; });
let nextId = 1;
const pending = new Map();
const consoleErrors = [];
ws.onmessage = (event) => {
  const msg = JSON.parse(event.data);
  if (msg.id && pending.has(msg.id)) {
    const { resolve, reject } = pending.get(msg.id);
    pending.delete(msg.id);
    if (msg.error) reject(new Error(msg.error.message)); else resolve(msg.result);
  } else if (msg.method === 'Runtime.consoleAPICalled' && (msg.params.type === 'error' || msg.params.type === 'assert')) {
    consoleErrors.push(msg.params.args.map((a) => a.value ?? a.description).join(' '));
  } else if (msg.method === 'Runtime.exceptionThrown') {
    consoleErrors.push(msg.params.exceptionDetails.exception?.description ?? msg.params.exceptionDetails.text);
  } else if (msg.method === 'Log.entryAdded' && msg.params.entry.level === 'error') {
    consoleErrors.push(`${msg.params.entry.text} ${msg.params.entry.url ?? ''}`);
  }
};
const send = (method, params = {}) => new Promise((resolve, reject) => {
  const id = nextId++;
  pending.set(id, { resolve, reject });
  ws.send(JSON.stringify({ id, method, params }));
});
/// The value of an expression in the page (promises awaited).
async function evaluate(expression) {
  const r = await send('Runtime.evaluate', { expression, awaitPromise: true, returnByValue: true });
  if (r.exceptionDetails) throw new Error(`${expression}: ${r.exceptionDetails.exception?.description ?? r.exceptionDetails.text}`);
  return r.result.value;
}

await send('Runtime.enable');
await send('Log.enable');
await send('Page.enable');
const loaded = new Promise((resolve) => {
  const previous = ws.onmessage;
  ws.onmessage = (event) => { previous(event); if (JSON.parse(event.data).method === 'Page.loadEventFired') resolve(); };
});
let url = urlArg;
if (live) {
  // The run starts once the browser is up: the page must see it from its first scans.
  hmap = spawn(rest[0], rest.slice(1), { stdio: ['ignore', 'pipe', 'pipe'] });
  hmap.on('error', (e) => finish({ error: `${rest[0]} did not start: ${e.message}` }, 1));
  url = await new Promise((resolve) => {
    const take = (d) => {
      hmapOutput += d;
      const m = hmapOutput.match(/open (http:\/\/\S+)/);
      if (m) resolve(m[1]);
    };
    hmap.stdout.on('data', take);
    hmap.stderr.on('data', take);
    hmap.on('exit', (code) => finish({ error: `hmap exited (${code}) before serving: ${hmapOutput.slice(-600)}` }, 1));
  });
  hmap.removeAllListeners('exit');
}
const navigateAt = Date.now();
await send('Page.navigate', { url: points.length ? `${url}?view=top&flat=1` : url });
await loaded;
for (let k = 0; k < 200 && !(await evaluate('!!window.hmapViewer')); ++k) await new Promise((r) => setTimeout(r, 25));
const result = { chromium_ms: navigateAt - started };
if (live) {
  // What the page shows, every 100 ms, kept when it changes: the progress line, the map version
  // drawn, its boxes and trajectory points, whether tiles are still coming. Until the run says
  // done and the page has drawn that last map.
  try {
    await evaluate('window.hmapViewer.ready');
    result.ready_ms = Date.now() - navigateAt;
    const state = `(() => { const v = window.hmapViewer; return { progress: document.getElementById('progress').textContent,
      version: v.version, boxes: v.boxesDrawn, on_screen: v.boxesOnScreen(), poses: v.trajectoryDrawn, hvoxels: v.info.hvoxels, busy: v.busy() }; })()`;
    const samples = [];
    let last = '';
    for (;;) {
      const s = await evaluate(state);
      const key = JSON.stringify(s);
      if (key !== last) { samples.push({ ms: Date.now() - navigateAt, ...s }); last = key; }
      if (s.progress.startsWith('done:') && !s.busy) {
        // The last event may still be on its way to the page's reload: done once it is drawn.
        const served = await (await fetch(new URL('/api/status', url))).json();
        if (served.version === s.version) break;
      }
      await new Promise((r) => setTimeout(r, 100));
    }
    result.samples = samples;
    const shot = await send('Page.captureScreenshot', { format: 'png' });
    writeFileSync(join(outDir, 'view_live.png'), Buffer.from(shot.data, 'base64'));
  } catch (e) {
    result.error = e.message;
  }
  // Stopped as a user would (Ctrl-C's signal); its exit code and what it printed. The console
  // errors are those before: a stopped server breaks the page's event stream.
  result.console_errors = consoleErrors.slice();
  hmap.kill('SIGTERM');
  const timer = setTimeout(() => hmap.kill('SIGKILL'), 10000);
  result.hmap_exit = await new Promise((resolve) => {
    if (hmap.exitCode !== null) resolve(hmap.exitCode); else hmap.on('exit', (code, signal) => resolve(code ?? signal));
  });
  clearTimeout(timer);
  result.hmap_output = hmapOutput;
  finish(result);
}
try {
  await evaluate("window.hmapViewer.ready");
  result.ready_ms = Date.now() - navigateAt;
  await evaluate('window.hmapViewer.settled()');
  result.open_ms = Date.now() - navigateAt;
  result.page_timing = await evaluate('({...hmapViewer.timing, ...hmapViewer.spent})');
  result.chromium_cpu_s = chromiumCpuSeconds();
  // Where the time went: each request's start and end (ms since navigation), the document's.
  result.resource_timing = await evaluate(`performance.getEntries().filter((e) => e.entryType === 'resource' || e.entryType === 'navigation')
    .map((e) => [e.name.replace(location.origin, ''), Math.round(e.startTime), Math.round(e.responseStart), Math.round(e.responseEnd), e.transferSize])`);
  result.info = await evaluate('({hvoxels: hmapViewer.info.hvoxels, tiles: hmapViewer.info.tiles.length})');
  result.boxes_drawn = await evaluate('hmapViewer.boxesDrawn');
  const shot = await send('Page.captureScreenshot', { format: 'png' });
  writeFileSync(join(outDir, points.length ? 'view_top.png' : 'view.png'), Buffer.from(shot.data, 'base64'));
  if (!points.length) {
    result.fps = await evaluate('hmapViewer.measureFps(1000)');
    result.boxes_drawn_turning = await evaluate('hmapViewer.boxesDrawn');
    throw null;  // measured: nothing more to do
  }
  // The canvas under each point, every layer on, then without the HVoxels.
  const sample = `(() => { const [w, h, px] = hmapViewer.pixels(); const dpr = window.devicePixelRatio;
    return ${JSON.stringify(points)}.map(([x, y, z]) => { const [sx, sy] = hmapViewer.toScreen(x, y, z);
      const col = Math.round(sx * dpr), row = h - 1 - Math.round(sy * dpr); const k = 4 * (row * w + col);
      return [sx, sy, px[k], px[k + 1], px[k + 2]]; }); })()`;
  result.background = await evaluate(`(() => { const [w, h, px] = hmapViewer.pixels(); return [px[0], px[1], px[2]]; })()`);
  result.with_hvoxels = await evaluate(sample);
  result.distinct_colours = await evaluate(`(() => { const [w, h, px] = hmapViewer.pixels(); const s = new Set();
    for (let k = 0; k < px.length; k += 4) s.add((px[k] << 16) | (px[k + 1] << 8) | px[k + 2]); return s.size; })()`);
  await evaluate(`document.getElementById('layer-hvoxels').click()`);  // the checkbox, as a user would
  result.without_hvoxels = await evaluate(sample);
  await evaluate(`document.getElementById('layer-hvoxels').click()`);
  // The height slider at 0.5 m, moved as a user would (an input event on the range); the ground
  // patches off, which lie over the floor there.
  await evaluate(`document.getElementById('layer-ground').click()`);
  result.with_cut = await evaluate(`(() => { const [lo, hi] = hmapViewer.info.z_range; const s = document.getElementById('cut');
    s.value = String(Math.round(1000 * (0.5 - lo) / (hi - lo))); s.dispatchEvent(new Event('input')); return ${sample}; })()`);
  await evaluate(`(() => { const s = document.getElementById('cut'); s.value = '1000'; s.dispatchEvent(new Event('input')); })()`);
  await evaluate(`document.getElementById('layer-ground').click()`);
  // A real click on the first point: its column from the page.
  await evaluate('hmapViewer.renderNow()');
  const [sx, sy] = result.with_hvoxels[0];
  for (const type of ['mousePressed', 'mouseReleased']) {
    await send('Input.dispatchMouseEvent', { type, x: sx, y: sy, button: 'left', buttons: type === 'mousePressed' ? 1 : 0, clickCount: 1 });
  }
  for (let k = 0; k < 200 && !(await evaluate('!!hmapViewer.lastColumn')); ++k) await new Promise((r) => setTimeout(r, 25));
  result.column = await evaluate('hmapViewer.lastColumn');
  result.column_panel = await evaluate(`document.getElementById('column').dataset.column ?? null`);
  result.fps = await evaluate('hmapViewer.measureFps(1000)');
} catch (e) {
  if (e !== null) result.error = e.message;
}
result.console_errors = consoleErrors;
finish(result);
