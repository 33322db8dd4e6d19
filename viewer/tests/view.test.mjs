// kinegen view's page in headless Chromium: it loads with no console error and no request; at
// slider row k every joint, point and body outline is drawn where the CSV's row k puts it
// (within 0.5 px, read back from the DOM; the truth is the CSV of `kinegen analyze` and the
// mechanism file's geometry), as `kinegen animate --frame k` draws it; a plot's cursor shows the
// CSV's values exactly; hovering names things and shows their values; bad input (a CSV of
// another mechanism or other parameters, an empty one, a ragged one, a million rows) gets a
// clear error or a decimated view, never a blank page. Run: node --test viewer/tests/
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { test } from 'node:test';

import { drawn, kinegen, legends, notes, open, readCsv, scratch, slide, SOURCE, toPixels,
         TURN } from './support.mjs';

const FOUR_BAR = path.join(SOURCE, 'examples/four_bar.yaml');
const PLANETARY = path.join(SOURCE, 'examples/gears/planetary.yaml');
const PRESS = path.join(SOURCE, 'examples/forces/press.yaml');
const TOL = 0.5;  // pixels
// examples/four_bar.yaml's geometry: a, b, c, d, px, py.
const FB = { a: 1, b: 3.5, c: 2.5, d: 3, px: 1.5, py: 1 };

function world(q, body, s) {
  const x = q[body + '.x'], y = q[body + '.y'], phi = q[body + '.phi'];
  return [x + Math.cos(phi) * s[0] - Math.sin(phi) * s[1],
          y + Math.sin(phi) * s[0] + Math.cos(phi) * s[1]];
}

function rowOf(csv, k) {
  const out = {};
  csv.header.forEach((h, c) => { out[h] = csv.columns[c][k]; });
  return out;
}

function near(got, want, what) {
  const d = Math.hypot(got[0] - want[0], got[1] - want[1]);
  assert.ok(d <= TOL, `${what}: drawn at (${got}), the CSV puts it at (${want.map((v) =>
    v.toFixed(2))}): ${d.toFixed(3)} px off`);
}

// Every drawn vertex is one of `want` and every one of `want` is drawn (pixels).
function sameSet(got, want, what) {
  assert.equal(got.length, want.length, what + ': ' + got.length + ' vertices');
  for (const g of got)
    assert.ok(want.some((w) => Math.hypot(g[0] - w[0], g[1] - w[1]) <= TOL),
              `${what}: a vertex at (${g}) where none should be`);
  for (const w of want)
    assert.ok(got.some((g) => Math.hypot(g[0] - w[0], g[1] - w[1]) <= TOL),
              `${what}: nothing drawn at (${w})`);
}

function fourBarCsv(dir, steps = 360) {
  const csv = path.join(dir, 'four_bar.csv');
  const r = kinegen('analyze', FOUR_BAR, '--t0', '0', '--t1', TURN, '--steps', String(steps),
                    '-o', csv);
  assert.equal(r.code, 0, r.err);
  return csv;
}

function view(...args) {
  const r = kinegen('view', ...args);
  assert.equal(r.code, 0, r.err);
  return r;
}

function clean(log) {
  assert.deepEqual(log.console, [], 'console errors or warnings');
  assert.deepEqual(log.errors, [], 'uncaught errors');
  assert.deepEqual(log.requests, [], 'requests besides the page itself');
}

// The four-bar's joints, points and outlines at row q (world), from the file's geometry and the
// CSV's point columns.
function fourBarTruth(q) {
  const A = [q['A.x'], q['A.y']], B = [q['B.x'], q['B.y']], P = [q['P.x'], q['P.y']];
  return {
    pins: { 'joints[0] (revolute)': [0, 0], 'joints[1] (revolute)': A,
            'joints[2] (revolute)': B, 'joints[3] (revolute)': [FB.d, 0] },
    points: { A, B, P },
    bodies: { crank: [world(q, 'crank', [0, 0]), world(q, 'crank', [FB.a, 0])],
              coupler: [world(q, 'coupler', [0, 0]), world(q, 'coupler', [FB.b, 0]),
                        world(q, 'coupler', [FB.px, FB.py])],
              rocker: [world(q, 'rocker', [0, 0]), world(q, 'rocker', [FB.c, 0])] },
  };
}

function checkFourBar(d, truth, what) {
  assert.equal(d.pins.length, 4, what + ': four pins');
  for (const pin of d.pins) near([pin.x, pin.y], toPixels(d.map, truth.pins[pin.name]), `${what} pin ${pin.name}`);
  assert.equal(d.points.length, 3, what + ': three points');
  for (const p of d.points) near([p.x, p.y], toPixels(d.map, truth.points[p.name]), `${what} point ${p.name}`);
  assert.equal(d.bodies.length, 3);
  for (const b of d.bodies)
    sameSet(b.points, truth.bodies[b.name].map((w) => toPixels(d.map, w)), `${what} body ${b.name}`);
}

test('four-bar: joints, points and bodies where the CSV puts them; plot cursors show its values',
     async () => {
  const dir = scratch('four_bar');
  const csvFile = fourBarCsv(dir);
  const html = path.join(dir, 'four_bar.html');
  view(FOUR_BAR, '--csv', csvFile, '-o', html);
  const csv = readCsv(csvFile);
  const { page, log, close } = await open(html);
  try {
    assert.deepEqual(await notes(page), { error: '', notes: [] });
    for (const k of [0, 1, 97, 180, 299, 360]) {
      await slide(page, k);
      const q = rowOf(csv, k);
      checkFourBar(await drawn(page), fourBarTruth(q), 'row ' + k);
      // The plots' legends at the slider's row: the CSV's numbers, exactly.
      const shown = await legends(page);
      assert.ok(shown.length >= 2, 'two plots at first');
      for (const legend of shown) {
        assert.ok(Object.keys(legend).length >= 3);
        for (const [name, text] of Object.entries(legend))
          assert.equal(Number(text), q[name], `row ${k}: ${name} shows ${text}`);
      }
      const label = await page.textContent('#kg-time');
      assert.match(label, new RegExp('row ' + k + ' of 360'));
    }
    clean(log);
  } finally {
    await close();
  }
});

test('four-bar: the page draws row k as kinegen animate --frame k does', async () => {
  const dir = scratch('four_bar_animate');
  const html = path.join(dir, 'four_bar.html'), svg = path.join(dir, 'frame.svg');
  const k = 97;
  view(FOUR_BAR, '--t0', '0', '--t1', TURN, '--steps', '360', '-o', html);
  const r = kinegen('animate', FOUR_BAR, '--t0', '0', '--t1', TURN, '--steps', '360', '--frame',
                    String(k), '-o', svg);
  assert.equal(r.code, 0, r.err);
  const text = fs.readFileSync(svg, 'utf8');
  const attr = (name) => Number(text.match(new RegExp(name + '="([-0-9.e+]+)"'))[1]);
  const circles = (style) => [...text.matchAll(new RegExp(
    `<circle ${style} cx="([-0-9.]+)" cy="([-0-9.]+)"`, 'g'))].map((m) => [+m[1], +m[2]]);
  const pins = circles('r="5" fill="#ffffff" stroke="#222222" stroke-width="2"');
  const points = circles('r="3.5" fill="#d62728"');
  assert.equal(pins.length, 4);
  const { page, log, close } = await open(html);
  try {
    await slide(page, k);
    const d = await drawn(page);
    for (const [name, v] of [['scale', 'data-kinegen-scale'], ['x0', 'data-kinegen-x0'],
                             ['y0', 'data-kinegen-y0']])
      assert.equal(d.map[name], attr(v), 'the pixel map of animate: ' + name);
    assert.equal(d.width, attr('width'));
    sameSet(d.pins.map((p) => [p.x, p.y]), pins, 'pins as animate draws them');
    sameSet(d.points.map((p) => [p.x, p.y]), points, 'points as animate draws them');
    clean(log);
  } finally {
    await close();
  }
});

test('four-bar: hovering a plot moves the slider; hovering the drawing names and reads out',
     async () => {
  const dir = scratch('four_bar_hover');
  const csvFile = fourBarCsv(dir);
  const html = path.join(dir, 'four_bar.html');
  view(FOUR_BAR, '--csv', csvFile, '-o', html);
  const csv = readCsv(csvFile);
  const { page, log, close } = await open(html);
  try {
    const over = await page.locator('.kg-plot').first().locator('.u-over').boundingBox();
    await page.mouse.move(over.x + over.width * 0.37, over.y + over.height / 2);
    await page.waitForTimeout(100);
    const k = Number(await page.inputValue('#kg-slider'));
    assert.ok(k > 100 && k < 160, 'the slider follows the plot cursor: row ' + k);
    const q = rowOf(csv, k);
    checkFourBar(await drawn(page), fourBarTruth(q), 'row ' + k + ' from the plot');
    const [first, second] = await legends(page);
    for (const legend of [first, second])
      for (const [name, text] of Object.entries(legend)) assert.equal(Number(text), q[name], name);
    // The mouse leaves the plot: the cursor stays at the slider's row.
    await page.mouse.move(5, 5);
    await page.waitForTimeout(100);
    for (const [name, text] of Object.entries((await legends(page))[0]))
      assert.equal(Number(text), q[name], name + ' after the mouse left');

    // A body: its name and its columns at the row.
    const box = await page.locator('#kinegen-drawing').boundingBox();
    const d = await drawn(page);
    const coupler = d.bodies.find((b) => b.name === 'coupler').points;
    const c = coupler.reduce((s, p) => [s[0] + p[0] / 3, s[1] + p[1] / 3], [0, 0]);
    await page.mouse.move(box.x + c[0], box.y + c[1]);
    let tip = await page.textContent('#kg-tip');
    assert.match(tip, /^body: coupler/);
    assert.ok(tip.includes('coupler.phi = ' + String(q['coupler.phi'])), tip);
    assert.ok(tip.includes('coupler.omega = ' + String(q['coupler.omega'])), tip);
    // A point over a joint over a body: each, with its name and its values.
    const pin = d.pins.find((p) => p.name === 'joints[2] (revolute)');
    await page.mouse.move(box.x + pin.x, box.y + pin.y);
    tip = await page.textContent('#kg-tip');
    assert.match(tip, /^point: B\nB\.x = (\S+)\n/);
    assert.ok(tip.includes('B.x = ' + String(q['B.x']) + '\nB.y = ' + String(q['B.y'])), tip);
    assert.match(tip, /\n\npin: joints\[2\] \(revolute\)\nat x = /);
    const [, x, y] = tip.match(/at x = (\S+), y = (\S+)/);
    assert.ok(Math.abs(Number(x) - q['B.x']) < 1e-12 && Math.abs(Number(y) - q['B.y']) < 1e-12, tip);
    assert.match(tip, /\n\nbody: (coupler|rocker)\n/);
    // The slider moves under the mouse: the read-out follows.
    await slide(page, k + 1);
    const next = rowOf(csv, k + 1);
    tip = await page.textContent('#kg-tip');
    assert.ok(tip.includes('B.x = ' + String(next['B.x'])), tip);
    // Play moves on; pause stops.
    await page.click('#kg-play');
    await page.waitForTimeout(400);
    await page.click('#kg-play');
    const after = Number(await page.inputValue('#kg-slider'));
    assert.notEqual(after, k, 'play moved the slider');
    await page.waitForTimeout(200);
    assert.equal(Number(await page.inputValue('#kg-slider')), after, 'pause holds the row');
    // A plot of chosen columns: P.y against crank.phi.
    await page.selectOption('#kg-x', { label: 'crank.phi' });
    await page.selectOption('#kg-y', [{ label: 'P.y' }]);
    await page.click('#kg-add');
    const third = (await legends(page))[2];
    assert.deepEqual(Object.keys(third), ['crank.phi', 'P.y']);
    assert.equal(Number(third['P.y']), csv.col('P.y')[after]);
    clean(log);
  } finally {
    await close();
  }
});

test('planetary train: bearings, gears and the tooth where the analysis puts them', async () => {
  const dir = scratch('planetary');
  const html = path.join(dir, 'planetary.html'), csvFile = path.join(dir, 'planetary.csv');
  const grid = ['--t0', '0', '--t1', '4', '--steps', '240'];
  view(PLANETARY, ...grid, '-o', html);
  assert.equal(kinegen('analyze', PLANETARY, ...grid, '-o', csvFile).code, 0);
  const csv = readCsv(csvFile);
  const r_ring = 0.02 + 2 * 0.02;
  const { page, log, close } = await open(html);
  try {
    for (const k of [0, 61, 240]) {
      await slide(page, k);
      const q = rowOf(csv, k), d = await drawn(page);
      const planet = [q['planet.x'], q['planet.y']];
      const pins = Object.fromEntries(d.pins.map((p) => [p.name.split(':')[0], [p.x, p.y]]));
      near(pins.sun_bearing, toPixels(d.map, [0, 0]), 'sun bearing');
      near(pins.carrier_bearing, toPixels(d.map, [0, 0]), 'carrier bearing');
      near(pins.planet_bearing, toPixels(d.map, planet), 'planet bearing at row ' + k);
      near([d.points[0].x, d.points[0].y], toPixels(d.map, [q['tooth.x'], q['tooth.y']]), 'tooth');
      // Pitch circles: the sun's and the ring's about the centre, the planet's (twice) about it.
      const centre = toPixels(d.map, [0, 0]), planetCentre = toPixels(d.map, planet);
      const at = (g, w) => Math.hypot(g.x - w[0], g.y - w[1]) <= TOL;
      assert.equal(d.gears.length, 4, 'two meshes, two pitch circles each');
      for (const g of d.gears)
        assert.ok(at(g, centre) || at(g, planetCentre), `row ${k}: a pitch circle at (${g.x}, ${g.y})`);
      assert.equal(d.gears.filter((g) => at(g, planetCentre)).length, 2, 'the planet\'s, twice');
      const radii = await page.$$eval('circle[data-kind="gear"]', (cs) => cs.map((c) => +c.getAttribute('r')));
      assert.ok(radii.some((rr) => Math.abs(rr - r_ring * d.map.scale) <= TOL), 'the ring');
    }
    clean(log);
  } finally {
    await close();
  }
});

test('press with --forces: reaction arrows along the CSV\'s forces', async () => {
  const dir = scratch('press');
  const html = path.join(dir, 'press.html'), csvFile = path.join(dir, 'press.csv');
  const grid = ['--t0', '0', '--t1', '1', '--steps', '200', '--forces'];
  view(PRESS, ...grid, '-o', html);
  assert.equal(kinegen('analyze', PRESS, ...grid, '-o', csvFile).code, 0);
  const csv = readCsv(csvFile);
  const { page, log, close } = await open(html);
  try {
    const k = 90;  // in the pressing stroke
    await slide(page, k);
    const arrows = await page.$$eval('polyline[data-kind="reaction"]', (es) => es.map((e) => ({
      name: e.dataset.name,
      points: e.getAttribute('points').split(' ').map((p) => p.split(',').map(Number)) })));
    assert.ok(arrows.length >= 3, arrows.length + ' arrows');
    for (const a of arrows) {
      const base = a.name.split(':')[0];
      const fx = csv.col(base + '.fx')[k], fy = csv.col(base + '.fy')[k];
      const [tail, tip] = [a.points[0], a.points[3]];
      const dx = tip[0] - tail[0], dy = tip[1] - tail[1];
      if (Math.hypot(fx, fy) < 1e-6 * 5000) continue;
      // Along (fx, -fy) in pixels (y down).
      const cross = (dx * -fy - dy * fx) / (Math.hypot(dx, dy) * Math.hypot(fx, fy));
      assert.ok(Math.abs(cross) < 0.02 && dx * fx - dy * fy > 0, a.name + ' points along its force');
    }
    clean(log);
  } finally {
    await close();
  }
});

test('modes: each plays as an oscillation about the equilibrium', async () => {
  const dir = scratch('modes');
  const csv = readCsv(fourBarCsv(dir, 72));
  const q0 = rowOf(csv, 10);
  const bodies = ['crank', 'coupler', 'rocker'];
  const eq = [], shapes = [[], []];
  for (const b of bodies)
    for (const [c, v, a] of [['x', 'vx', 'ax'], ['y', 'vy', 'ay'], ['phi', 'omega', 'alpha']]) {
      eq.push(q0[b + '.' + c]);
      shapes[0].push(q0[b + '.' + v]);  // along the motion: the velocities
      shapes[1].push(-q0[b + '.' + v]);
    }
  const modes = path.join(dir, 'modes.json'), html = path.join(dir, 'modes.html');
  fs.writeFileSync(modes, JSON.stringify({ coordinates: bodies.flatMap((b) => ['x', 'y', 'phi'].map((c) => b + '.' + c)),
                                           q: eq, frequencies: [3.5, 12.25], shapes }));
  view(FOUR_BAR, '--modes', modes, '-o', html);
  const { page, log, close } = await open(html);
  try {
    const amplitudes = await page.evaluate(() => window.kinegen.data.modes.amplitudes);
    for (const [mode, k] of [[0, 0], [0, 30], [0, 77], [1, 30]]) {
      await page.selectOption('#kg-mode', String(mode));
      await slide(page, k);
      const s = Math.sin(2 * Math.PI * k / 120), q = {};
      bodies.forEach((b, i) => ['x', 'y', 'phi'].forEach((c, j) => {
        q[b + '.' + c] = eq[3 * i + j] + amplitudes[mode] * s * shapes[mode][3 * i + j];
      }));
      const d = await drawn(page);
      const truth = fourBarTruth(Object.assign({}, q, { 'A.x': 0, 'A.y': 0, 'B.x': 0, 'B.y': 0,
                                                        'P.x': 0, 'P.y': 0 }));
      for (const b of d.bodies)
        sameSet(b.points, truth.bodies[b.name].map((w) => toPixels(d.map, w)),
                `mode ${mode + 1} phase row ${k}: ${b.name}`);
      assert.match(await page.textContent('#kg-frequency'), mode ? /12\.25 Hz/ : /3\.5 Hz/);
    }
    clean(log);
  } finally {
    await close();
  }
});

test('a simulated run: the press drawn where kinegen simulate puts it, its energy plotted',
     async () => {
  // A mechanism with free: coordinates, viewed from its simulation's CSV (the free coordinate is
  // state there, not an input that needs a table).
  const dir = scratch('simulated');
  const yaml = path.join(SOURCE, 'examples/dynamics/press_flywheel.yaml');
  const csvFile = path.join(dir, 'press_flywheel.csv'), html = path.join(dir, 'press.html');
  const r = kinegen('simulate', yaml, '--t1', '2', '--steps', '100', '-q', '-o', csvFile);
  assert.equal(r.code, 0, r.err);
  view(yaml, '--csv', csvFile, '-o', html);
  const csv = readCsv(csvFile);
  const { page, log, close } = await open(html);
  try {
    assert.deepEqual(await notes(page), { error: '', notes: [] });
    await page.selectOption('#kg-x', { label: 't' });
    await page.selectOption('#kg-y', [{ label: 'theta.v' }, { label: 'energy.balance' }]);
    await page.click('#kg-add');
    for (const k of [0, 37, 100]) {
      await slide(page, k);
      const q = rowOf(csv, k), d = await drawn(page);
      const pin = (name) => d.pins.find((p) => p.name.startsWith(name + ':'));
      near([pin('crank_pin').x, pin('crank_pin').y], toPixels(d.map, world(q, 'crank', [0.05, 0])),
           `row ${k} crank_pin`);
      near([pin('wrist_pin').x, pin('wrist_pin').y], toPixels(d.map, world(q, 'rod', [0.2, 0])),
           `row ${k} wrist_pin`);
      const legend = (await legends(page)).find((l) => 'energy.balance' in l);
      assert.equal(Number(legend['energy.balance']), q['energy.balance'], `row ${k}`);
      assert.equal(Number(legend['theta.v']), q['theta.v'], `row ${k}`);
    }
    clean(log);
  } finally {
    await close();
  }
});

test('bad input: a clear error and no page', () => {
  const dir = scratch('bad');
  const four = fourBarCsv(dir, 36);
  const html = path.join(dir, 'out.html');
  const lines = fs.readFileSync(four, 'utf8').split('\n');
  const write = (name, text) => { const f = path.join(dir, name); fs.writeFileSync(f, text); return f; };
  const slider = path.join(dir, 'slider.csv');
  assert.equal(kinegen('analyze', path.join(SOURCE, 'examples/slider_crank.yaml'), '--t0', '0',
                       '--t1', '1', '--steps', '5', '-o', slider).code, 0);
  const other = path.join(dir, 'other.csv');
  assert.equal(kinegen('analyze', FOUR_BAR, '--param', 'c=2.6', '--t0', '0', '--t1', '1',
                       '--steps', '5', '-o', other).code, 0);
  const cases = [
    [slider, /slider\.csv:1: columns: not a run of .*four_bar\.yaml: no column coupler\.x, coupler\.y, coupler\.phi, rocker\.x/],
    [write('renamed.csv', lines.map((l, i) => (i ? l : l.replaceAll('crank.', 'arm.'))).join('\n')),
     /renamed\.csv:1: columns: not a run of .*: no column crank\.x, crank\.y, crank\.phi \(its columns: t, arm\.x/],
    [other, /other\.csv: row 0 \(t = 0\): the positions break joints\[2\] \(revolute\) x-component .* by 0\.\d+: a run of another mechanism, or made with other --param values\?/],
    [write('empty.csv', ''), /empty\.csv: header: the file is empty/],
    [write('header.csv', lines[0] + '\n'), /header\.csv:1: rows: a header but no rows/],
    [write('ragged.csv', lines.slice(0, 5).join('\n') + '\n1,2,3\n'), /ragged\.csv:6: row 4: 3 values where the header has 46 columns/],
    [write('text.csv', lines.slice(0, 3).join('\n') + '\n' + lines[3].replace(/^[^,]*/, 'zero') + '\n'),
     /text\.csv:4: row 2: 'zero' in column 't' is not a number/],
    [write('twice.csv', 't,t\n1,2\n'), /twice\.csv:1: header: the column 't' appears twice/],
  ];
  for (const [csv, message] of cases) {
    const r = kinegen('view', FOUR_BAR, '--csv', csv, '-o', html);
    assert.equal(r.code, 2, path.basename(csv) + ': ' + r.err);
    assert.match(r.err, /^error: /);
    assert.equal(r.err.trim().split('\n').length, 1, 'one line: ' + r.err);
    assert.match(r.err, message);
    assert.ok(!fs.existsSync(html), 'no page for ' + path.basename(csv));
  }
  const usage = kinegen('view', FOUR_BAR, '--csv', four, '--t0', '0', '-o', html);
  assert.equal(usage.code, 2);
  assert.match(usage.err, /view shows one of: --csv RUN.csv, --modes MODES.json, or an analysis/);
  const modes = write('modes.json', JSON.stringify({ q: [0, 0], frequencies: [1], shapes: [[1, 0]] }));
  const m = kinegen('view', FOUR_BAR, '--modes', modes, '-o', html);
  assert.equal(m.code, 2);
  assert.match(m.err, /modes\.json:1: q: 2 values, expected 9 \(one per coordinate: 9\)/);
});

test('a million rows: a decimated view, each value the CSV\'s own', async () => {
  const dir = scratch('million');
  const csv = readCsv(fourBarCsv(dir, 360));
  // One turn after another (each row a solved position), t increasing: t, q and the points.
  const keep = ['crank.x', 'crank.y', 'crank.phi', 'coupler.x', 'coupler.y', 'coupler.phi',
                'rocker.x', 'rocker.y', 'rocker.phi', 'P.x', 'P.y'];
  const turn = Array.from({ length: 360 }, (_, k) => keep.map((name) => String(csv.col(name)[k])).join(','));
  const text = (k) => turn[k % 360];
  const big = path.join(dir, 'million.csv'), total = 1000000, dt = 2 * Math.PI / 360;
  const fd = fs.openSync(big, 'w');
  fs.writeSync(fd, 't,' + keep.join(',') + '\n');
  for (let start = 0; start < total; start += 20000) {
    let chunk = '';
    for (let r = start; r < start + 20000; r++) chunk += String(r * dt) + ',' + text(r) + '\n';
    fs.writeSync(fd, chunk);
  }
  fs.closeSync(fd);
  const html = path.join(dir, 'million.html');
  const r = view(FOUR_BAR, '--csv', big, '-o', html);
  assert.match(r.err, /1000000 rows; the page keeps one in 6 and the last, 166668/);
  const { page, log, close } = await open(html);
  try {
    const n = await notes(page);
    assert.equal(n.error, '');
    assert.match(n.notes[0], /A long run: 1000000 rows, of which the page keeps one in 6 and the last \(166668 rows\)/);
    for (const k of [0, 12345, 166666, 166667]) {
      await slide(page, k);
      const row = k === 166667 ? total - 1 : 6 * k;
      const q = { 'A.x': 0 };
      keep.forEach((name) => { q[name] = csv.col(name)[row % 360]; });
      const d = await drawn(page);
      for (const b of d.bodies) {
        const truth = fourBarTruth(Object.assign({ 'A.y': 0, 'B.x': 0, 'B.y': 0 }, q));
        sameSet(b.points, truth.bodies[b.name].map((w) => toPixels(d.map, w)), `row ${row}: ${b.name}`);
      }
      const point = d.points.find((p) => p.name === 'P');
      near([point.x, point.y], toPixels(d.map, [q['P.x'], q['P.y']]), 'P at row ' + row);
      assert.match(await page.textContent('#kg-time'), new RegExp('row ' + row + ' of 999999'));
      const legend = (await legends(page))[0];
      assert.equal(Number(legend.t), row * dt);
      assert.equal(Number(legend['coupler.phi']), q['coupler.phi']);
    }
    clean(log);
  } finally {
    await close();
  }
});

test('a run that stops early: the page of the rows before, and why', async () => {
  const dir = scratch('stops');
  // The rocker driven past the end of its swing: the step to t = 1.7 fails, and its sub-steps
  // stop near t = 1.69, where the linkage cannot follow.
  const yaml = path.join(dir, 'rocker_driven.yaml'), html = path.join(dir, 'stops.html');
  fs.writeFileSync(yaml, fs.readFileSync(FOUR_BAR, 'utf8').replace(
    'body: crank\n    f: "omega*t"', 'body: rocker\n    f: "1.3694384060045657 + 0.5*t"'));
  const r = kinegen('view', yaml, '--t0', '0', '--t1', '4', '--steps', '80', '-o', html);
  assert.equal(r.code, 1);
  assert.match(r.err, /^error: .*position analysis failed at t = 1\.6[89]\d* \(in sub-steps of the step from t = 1\.649\d* to t = 1\.7,/m);
  const { page, log, close } = await open(html);
  try {
    const n = await notes(page);
    assert.equal(n.error, '');
    assert.match(n.notes[0], /^The run stops early: .*failed at t = 1\.6[89].* The page shows the rows before it\.$/);
    assert.equal(await page.getAttribute('#kg-slider', 'max'), '33');
    clean(log);
  } finally {
    await close();
  }
});

test('a damaged page says so rather than show nothing', async () => {
  const dir = scratch('damaged');
  const html = path.join(dir, 'four_bar.html'), cut = path.join(dir, 'cut.html');
  view(FOUR_BAR, '--t0', '0', '--t1', TURN, '--steps', '90', '-o', html);
  const text = fs.readFileSync(html, 'utf8');
  const at = text.indexOf('id="kinegen-values">') + 20;
  fs.writeFileSync(cut, text.slice(0, at + 4000) + text.slice(text.indexOf('</script>', at)));
  const { page, log, close } = await open(cut);
  try {
    const n = await notes(page);
    assert.match(n.error, /^The page could not show this run: the page's data does not inflate \(.*\): the file is cut short or damaged$/);
    assert.deepEqual(log.errors, []);
    assert.deepEqual(log.requests, []);
  } finally {
    await close();
  }
});

// ---- Everything drawn: bodies without named points, springs and dampers, loads, modes of
// sliders, tall mechanisms.

// A rod on a pivot at its frame's origin, its centre of mass at [a, 0], no named point.
const BARE_PENDULUM = `name: bare_pendulum
parameters: {m: 1.0, a: 0.5, g: 9.81}
gravity: [0, -g]
bodies:
  - {name: rod, q0: [0, 0, 0], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
joints:
  - {type: revolute, name: pivot, i: ground, j: rod}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: "-pi/2 + 0.05"}
`;
// Two blocks on a rail, each on a prismatic joint at its origin (no named point): a spring from
// the ground to the first, a spring and a damper side by side between them, a push on the second.
const TWO_MASSES = `name: two_masses
parameters: {k: 100, c: 0.5}
bodies:
  - {name: m1, q0: [1, 0, 0], mass: 1}
  - {name: m2, q0: [2, 0, 0], mass: 1}
joints:
  - {type: translational, name: rail1, i: ground, j: m1, vi: [1, 0]}
  - {type: translational, name: rail2, i: ground, j: m2, vi: [1, 0]}
free:
  - {type: absolute_x, name: x1, body: m1, value0: 1.1}
  - {type: absolute_x, name: x2, body: m2, value0: 2}
forces:
  - {type: spring_damper, name: s1, i: ground, j: m1, si: [0, 0], sj: [0, 0], stiffness: k, length0: 1}
  - {type: spring_damper, name: s2, i: m1, j: m2, stiffness: k, damping: c, length0: 1}
  - {type: force, name: push, body: m2, f: [-1, 0]}
`;

// The strokes' points of a path's d ("M x,y L x,y ...").
function pathPoints(d) {
  return d.trim().split(/\s+/).map((p) => p.slice(1).split(',').map(Number));
}

function simulated(dir, name, yaml, steps = 40) {
  const file = path.join(dir, name + '.yaml'), csvFile = path.join(dir, name + '.csv');
  fs.writeFileSync(file, yaml);
  const r = kinegen('simulate', file, '--t1', '1', '--steps', String(steps), '-q', '-o', csvFile);
  assert.equal(r.code, 0, r.err);
  return { file, csv: readCsv(csvFile), csvFile };
}

test('a body whose only joint is at its origin, with no named point, is drawn at its joint; a ' +
     'tall mechanism fits the page with its title', async () => {
  const dir = scratch('bare_pendulum');
  const { file, csv, csvFile } = simulated(dir, 'bare_pendulum', BARE_PENDULUM);
  const html = path.join(dir, 'page.html');
  view(file, '--csv', csvFile, '-o', html);
  const { page, log, close } = await open(html);
  try {
    for (const k of [0, 13, 40]) {
      await slide(page, k);
      const q = rowOf(csv, k), d = await drawn(page);
      const rod = d.bodies.find((b) => b.name === 'rod');
      assert.ok(rod, 'row ' + k + ': the rod is drawn');
      // Through its joint (the pivot, at the world's origin) and its centre of mass.
      const pivot = toPixels(d.map, [0, 0]), com = toPixels(d.map, world(q, 'rod', [0.5, 0]));
      for (const [want, what] of [[pivot, 'pivot'], [com, 'centre of mass']]) {
        const off = Math.min(...rod.points.map((p) => Math.hypot(p[0] - want[0], p[1] - want[1])));
        assert.ok(off <= 1, `row ${k}: the rod passes ${off.toFixed(2)} px from its ${what}`);
      }
      assert.ok(Math.hypot(com[0] - pivot[0], com[1] - pivot[1]) > 100, 'drawn large enough');
      near([d.pins[0].x, d.pins[0].y], pivot, 'row ' + k + ' pivot');
    }
    // Tall and narrow: the whole picture within the window, and its title within the picture.
    const fit = await page.evaluate(() => {
      const svg = document.getElementById('kinegen-drawing');
      const title = svg.querySelector('text').getBBox(), box = svg.getBoundingClientRect();
      return { titleRight: title.x + title.width, width: +svg.getAttribute('width'),
               bottom: box.bottom, right: box.right, viewport: [innerWidth, innerHeight] };
    });
    assert.ok(fit.titleRight <= fit.width, `the title ends at ${fit.titleRight} of ${fit.width}`);
    assert.ok(fit.bottom <= fit.viewport[1] && fit.right <= fit.viewport[0],
              `the picture ends at (${fit.right}, ${fit.bottom}) in a ${fit.viewport} window`);
    clean(log);
  } finally {
    await close();
  }
});

test('springs and dampers between their two points, loads where they act', async () => {
  const dir = scratch('two_masses');
  const { file, csv, csvFile } = simulated(dir, 'two_masses', TWO_MASSES);
  const html = path.join(dir, 'page.html');
  view(file, '--csv', csvFile, '-o', html);
  const { page, log, close } = await open(html);
  try {
    // The first plot: the blocks' x, which move (their angles are constant).
    assert.deepEqual(await page.evaluate(() => window.kinegen.plots[0].ycs.map((c) =>
      window.kinegen.run.names[c])), ['m1.x', 'm2.x']);
    for (const k of [0, 7, 40]) {
      await slide(page, k);
      const q = rowOf(csv, k), d = await drawn(page);
      const shapes = await page.$$eval('path[data-kind="spring"], path[data-kind="load"]',
        (es) => es.map((e) => ({ kind: e.dataset.kind, name: e.dataset.name, d: e.getAttribute('d') })));
      const m1 = toPixels(d.map, world(q, 'm1', [0, 0])), m2 = toPixels(d.map, world(q, 'm2', [0, 0]));
      const ends = { s1: [toPixels(d.map, [0, 0]), m1], s2: [m1, m2] };
      for (const name of ['s1', 's2']) {
        const sp = shapes.find((s) => s.kind === 'spring' && s.name.includes(`'${name}'`));
        assert.ok(sp, `row ${k}: spring ${name} drawn`);
        const pts = pathPoints(sp.d);
        near(pts[0], ends[name][0], `row ${k}: ${name}'s first end`);
        near(pts[pts.length - 1], ends[name][1], `row ${k}: ${name}'s second end`);
        // A zig-zag: it leaves the line between its ends, on both sides.
        const [a, b] = ends[name], len = Math.hypot(b[0] - a[0], b[1] - a[1]);
        const side = pts.map((p) => ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) / len);
        assert.ok(Math.max(...side) >= 4 && Math.min(...side) <= -4, `row ${k}: ${name} zig-zags`);
      }
      // The damper beside s2: a dashpot's cylinder (strokes across the line), and the push on m2
      // as an arrow whose head is at m2's origin, pointing along -x.
      assert.ok(pathPoints(shapes.find((s) => s.name.includes("'s2'")).d).length > 20);
      const push = pathPoints(shapes.find((s) => s.kind === 'load').d);
      near(push[1], m2, `row ${k}: the push's head`);
      assert.ok(push[0][0] - push[1][0] > 30 && Math.abs(push[0][1] - push[1][1]) < 0.5,
                `row ${k}: the push comes from +x, along x`);
      // The blocks: each body is drawn at its joint (a disc about its origin).
      const discs = await page.$$eval('circle[data-kind="body"]', (es) => es.map((e) =>
        ({ name: e.dataset.name, x: +e.getAttribute('cx'), y: +e.getAttribute('cy') })));
      near([discs.find((c) => c.name === 'm1').x, discs.find((c) => c.name === 'm1').y], m1, 'm1');
      near([discs.find((c) => c.name === 'm2').x, discs.find((c) => c.name === 'm2').y], m2, 'm2');
    }
    clean(log);
  } finally {
    await close();
  }
});

test('modes of sliders: the first plot shows the coordinates that move', async () => {
  const dir = scratch('two_masses_modes');
  const file = path.join(dir, 'two_masses.yaml'), modes = path.join(dir, 'modes.json');
  const html = path.join(dir, 'modes.html');
  fs.writeFileSync(file, TWO_MASSES);
  const r = kinegen('modes', file, '--format', 'json', '-o', modes);
  assert.equal(r.code, 0, r.err);
  view(file, '--modes', modes, '-o', html);
  const { page, log, close } = await open(html);
  try {
    const series = await page.evaluate(() => window.kinegen.plots[0].ycs.map((c) => {
      const col = window.kinegen.run.column(c);
      return { name: window.kinegen.run.names[c], range: Math.max(...col) - Math.min(...col) };
    }));
    assert.deepEqual(series.map((s) => s.name), ['m1.x', 'm2.x']);
    for (const s of series) assert.ok(s.range > 1e-3, s.name + ' moves: ' + s.range);
    clean(log);
  } finally {
    await close();
  }
});
