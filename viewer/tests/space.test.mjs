// kinegen view of a spatial file (space: 3d) in headless Chromium: the page loads with no
// console error and no request but to itself and the blob: URLs it makes of its own three.js
// text; at slider row k each body of the 3D scene stands where the CSV's coordinates put it and
// each named point is where the CSV's P.x, P.y, P.z put it (to 1e-9, read back from three's
// scene: the page's own Euler-parameter transform checked), and the crank pin and the slider
// where the slider-crank's closed form puts them; the camera projects a point into the
// drawing; a planar page carries no three.js; what view still refuses on spatial files is one
// error line and exit 2. Run: node --test viewer/tests/
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { test } from 'node:test';

import { kinegen, open, readCsv, scratch, slide, SOURCE } from './support.mjs';

const CRANK = path.join(SOURCE, 'tests/mechanisms/spatial_slider_crank.yaml');
const FOUR_BAR = path.join(SOURCE, 'examples/four_bar.yaml');
const PERIOD = String((2 * Math.PI) / 6);  // omega = 6: one turn of the crank
const TOL = 1e-9;

// The file's closed form at crank angle th: the pin P = (0, 0.1 - 0.08 sin th,
// 0.12 + 0.08 cos th) and the slider's x = sqrt(0.09 - P.y^2 - P.z^2) on the x axis.
function truth(th) {
  const py = 0.1 - 0.08 * Math.sin(th), pz = 0.12 + 0.08 * Math.cos(th);
  return { P: [0, py, pz], S: [Math.sqrt(0.09 - py * py - pz * pz), 0, 0] };
}

// Requests that leave the page: none may; the blob: URLs of its own modules stay in it. The
// software GL of headless Chromium (--disable-gpu) logs its performance notes as warnings
// ("GL Driver Message (OpenGL, Performance, ...)"): those are the test machine's, not the page's.
function clean(log) {
  assert.deepEqual(log.console.filter((m) => !/GL Driver Message \(OpenGL, Performance/.test(m)),
                   [], 'console errors or warnings');
  assert.deepEqual(log.errors, [], 'uncaught errors');
  assert.deepEqual(log.requests.filter((u) => !u.startsWith('blob:')), [],
                   'requests besides the page itself');
}

// What three's scene holds at the slider's row: each body group's position and quaternion
// (x, y, z, w), each named point's world position, and where the camera projects them (pixels
// in the canvas, and whether inside it).
async function sceneNow(page) {
  return page.evaluate(() => {
    const d = window.kinegen.space, out = { bodies: {}, points: {}, pixels: {} };
    for (const g of d.groups)
      out.bodies[g.name] = { r: g.position.toArray(), p: g.quaternion.toArray() };
    const canvas = d.renderer.domElement;
    for (const [name, m] of Object.entries(d.pointMeshes)) {
      const w = m.getWorldPosition(m.position.clone());
      out.points[name] = w.toArray();
      const ndc = w.clone().project(d.camera);
      out.pixels[name] = [(ndc.x + 1) / 2 * canvas.width, (1 - ndc.y) / 2 * canvas.height,
                          Math.abs(ndc.x) < 1 && Math.abs(ndc.y) < 1 && Math.abs(ndc.z) < 1];
    }
    return out;
  });
}

function close3(got, want, what) {
  const d = Math.hypot(got[0] - want[0], got[1] - want[1], got[2] - want[2]);
  assert.ok(d <= TOL, `${what}: (${got}) where (${want}) is: ${d} off`);
}

test('spatial slider-crank: bodies and points where the CSV and the closed form put them; ' +
     'scrubbing moves the slider', async () => {
  const dir = scratch('space');
  const csv = path.join(dir, 'crank.csv'), html = path.join(dir, 'crank.html');
  let r = kinegen('analyze', CRANK, '--t0', '0', '--t1', PERIOD, '--steps', '120', '-o', csv);
  assert.equal(r.code, 0, r.err);
  r = kinegen('view', CRANK, '--csv', csv, '-o', html);
  assert.equal(r.code, 0, r.err);
  const run = readCsv(csv);
  const { page, log, close } = await open(html);
  try {
    clean(log);
    assert.equal(await page.evaluate(() => window.kinegen.space.THREE.REVISION), '185');
    const xs = [];
    for (const k of [0, 17, 60, 101, 120]) {
      await slide(page, k);
      const s = await sceneNow(page), t = run.col('t')[k];
      for (const b of ['crank', 'rod', 'slider']) {
        const at = ['x', 'y', 'z'].map((c) => run.col(`${b}.${c}`)[k]);
        const p = ['e1', 'e2', 'e3', 'e0'].map((c) => run.col(`${b}.${c}`)[k]);
        close3(s.bodies[b].r, at, `row ${k}: ${b}'s origin`);
        assert.deepEqual(s.bodies[b].p, p, `row ${k}: ${b}'s Euler parameters`);
      }
      for (const name of ['P', 'S'])
        close3(s.points[name], ['x', 'y', 'z'].map((c) => run.col(`${name}.${c}`)[k]),
               `row ${k}: point ${name} against the CSV`);
      const want = truth(6 * t);
      close3(s.points.P, want.P, `row ${k}: the crank pin against the closed form`);
      close3(s.points.S, want.S, `row ${k}: the slider against the closed form`);
      assert.ok(s.pixels.P[2] && s.pixels.S[2], `row ${k}: P and S in the camera's view`);
      xs.push(s.bodies.slider.r[0]);
    }
    // The slider moves along x with the slider's row (from 0.185 to 0.290 over the turn).
    assert.ok(Math.max(...xs) - Math.min(...xs) > 0.08, 'slider x over the rows: ' + xs);
    // Turning the view (OrbitControls) moves the camera, not the mechanism.
    const before = await sceneNow(page);
    const box = await page.locator('#kg-drawing-box canvas').boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.mouse.down();
    await page.mouse.move(box.x + box.width / 2 + 120, box.y + box.height / 2 + 40, { steps: 6 });
    await page.mouse.up();
    const after = await sceneNow(page);
    assert.deepEqual(after.points, before.points);
    assert.ok(Math.hypot(after.pixels.P[0] - before.pixels.P[0],
                         after.pixels.P[1] - before.pixels.P[1]) > 5, 'the view turned');
    // The first plots: against t; the bodies' moving coordinates and the points'.
    const plotted = await page.evaluate(() => window.kinegen.plots.map((p) =>
      [window.kinegen.run.names[p.xc], p.ycs.map((c) => window.kinegen.run.names[c])]));
    assert.equal(plotted[0][0], 't');
    assert.ok(plotted[0][1].includes('slider.x'), JSON.stringify(plotted));
    assert.ok(plotted[1][1].includes('P.z'), JSON.stringify(plotted));
    clean(log);
  } finally {
    await close();
  }
});

test('spatial slider-crank analysed by view itself: the values of analyze\'s CSV', async () => {
  const dir = scratch('space-analysis');
  const csv = path.join(dir, 'crank.csv'), html = path.join(dir, 'crank.html');
  let r = kinegen('analyze', CRANK, '--t0', '0', '--t1', '1', '--steps', '40', '-o', csv);
  assert.equal(r.code, 0, r.err);
  r = kinegen('view', CRANK, '--t0', '0', '--t1', '1', '--steps', '40', '-o', html);
  assert.equal(r.code, 0, r.err);
  const run = readCsv(csv);
  const { page, log, close } = await open(html);
  try {
    clean(log);
    const names = await page.evaluate(() => window.kinegen.run.names);
    assert.deepEqual(names, run.header);
    for (const name of ['slider.x', 'P.y', 'axle.z', 'crank.wx', 'slider_x']) {
      const got = await page.evaluate((c) => Array.from(window.kinegen.run.column(
        window.kinegen.run.names.indexOf(c))), name);
      assert.deepEqual(got, run.col(name), name);
    }
  } finally {
    await close();
  }
});

test('a run with wheel_travel: the first plots are against it, the suspension\'s outputs first',
     async () => {
  // The slider-crank's CSV with two columns a suspension's run has (docs/format.md, view):
  // wheel_travel increasing over the run, and toe.
  const dir = scratch('space-travel');
  const csv = path.join(dir, 'crank.csv'), html = path.join(dir, 'crank.html');
  const r = kinegen('analyze', CRANK, '--t0', '0', '--t1', '1', '--steps', '20', '-o', csv);
  assert.equal(r.code, 0, r.err);
  const lines = fs.readFileSync(csv, 'utf8').trimEnd().split('\n');
  fs.writeFileSync(csv, lines.map((l, k) => l + (k === 0 ? ',toe,wheel_travel'
    : ',' + (0.001 * k) + ',' + (0.005 * k - 0.05))).join('\n') + '\n');
  assert.equal(kinegen('view', CRANK, '--csv', csv, '-o', html).code, 0);
  const { page, log, close } = await open(html);
  try {
    clean(log);
    const got = await page.evaluate(() => ({
      x: document.getElementById('kg-x').selectedOptions[0].textContent,
      plots: window.kinegen.plots.map((p) =>
        [window.kinegen.run.names[p.xc], p.ycs.map((c) => window.kinegen.run.names[c])]) }));
    assert.equal(got.x, 'wheel_travel');
    assert.deepEqual(got.plots[0], ['wheel_travel', ['toe']]);
    assert.equal(got.plots[1][0], 'wheel_travel');
  } finally {
    await close();
  }
});

test('a planar page carries no three.js; a spatial one carries it once', () => {
  const dir = scratch('space-size');
  const planar = path.join(dir, 'four_bar.html'), spatial = path.join(dir, 'crank.html');
  let r = kinegen('view', FOUR_BAR, '--t0', '0', '--t1', '1', '--steps', '10', '-o', planar);
  assert.equal(r.code, 0, r.err);
  r = kinegen('view', CRANK, '--t0', '0', '--t1', '1', '--steps', '10', '-o', spatial);
  assert.equal(r.code, 0, r.err);
  const p = fs.readFileSync(planar, 'utf8'), s = fs.readFileSync(spatial, 'utf8');
  assert.ok(!p.includes('kg-three') && !p.includes('blob:'), 'the planar page has three.js');
  assert.equal(s.split('id="kg-three-core"').length, 2);
  assert.ok(s.includes("script-src 'unsafe-inline' blob:;"));
});

test('spatial files: what view refuses is one error line and exit 2', () => {
  const dir = scratch('space-refused');
  const html = path.join(dir, 'out.html');
  const modes = path.join(dir, 'modes.json');
  fs.writeFileSync(modes, '{"q": [], "frequencies": [], "shapes": []}');
  const cases = [
    ['view', CRANK, '--modes', modes, '-o', html],
    ['view', CRANK, '--t0', '0', '--t1', '1', '--steps', '4', '--forces', '-o', html],
    ['animate', CRANK, '--t0', '0', '--t1', '1', '--steps', '4', '-o', path.join(dir, 'a.svg')],
  ];
  for (const args of cases) {
    const r = kinegen(...args);
    assert.equal(r.code, 2, args.join(' ') + ': ' + r.err);
    const lines = r.err.trim().split('\n').filter((l) => l.startsWith('error:'));
    assert.equal(lines.length, 1, r.err);
    assert.match(lines[0], /spatial_slider_crank\.yaml/);
    assert.ok(!fs.existsSync(html), 'no page written');
  }
  // A run of other parameters: its points are not where its positions put them.
  const csv = path.join(dir, 'crank.csv'), other = path.join(dir, 'other.csv');
  let r = kinegen('analyze', CRANK, '--t0', '0', '--t1', '1', '--steps', '4', '-o', csv);
  assert.equal(r.code, 0, r.err);
  const rows = fs.readFileSync(csv, 'utf8').trimEnd().split('\n');
  const c = rows[0].split(',').indexOf('P.z');
  rows[3] = rows[3].split(',').map((v, k) => (k === c ? String(Number(v) + 0.01) : v)).join(',');
  fs.writeFileSync(other, rows.join('\n') + '\n');
  r = kinegen('view', CRANK, '--csv', other, '-o', html);
  assert.equal(r.code, 2, r.err);
  assert.match(r.err, /^error: .*point P is 0\.01 away/m);
  assert.ok(!fs.existsSync(html), 'no page written');
});
