// kinegen view's page: its size, load and scrub times for runs of 1e3, 1e5 and 1e6 rows of the
// four-bar (the CSV of kinegen analyze, all 46 columns). Prints numbers; asserts nothing.
//   node viewer/tests/bench.mjs [rows ...]      (KINEGEN_EXE, KINEGEN_TEST_TMP as for the tests)
import fs from 'node:fs';
import path from 'node:path';

import { kinegen, open, scratch, SOURCE, TURN } from './support.mjs';

const sizes = process.argv.slice(2).map(Number);
const FOUR_BAR = path.join(SOURCE, 'examples/four_bar.yaml');
const dir = scratch('bench');
const ms = (t) => t.toFixed(0);
const rows = [];
for (const n of sizes.length ? sizes : [1e3, 1e5, 1e6]) {
  const csv = path.join(dir, `four_bar_${n}.csv`), html = path.join(dir, `four_bar_${n}.html`);
  let r = kinegen('analyze', FOUR_BAR, '--t0', '0', '--t1', TURN, '--steps', String(n - 1), '-o', csv);
  if (r.code !== 0) throw new Error(r.err);
  let start = performance.now();
  r = kinegen('view', FOUR_BAR, '--csv', csv, '-o', html);
  if (r.code !== 0) throw new Error(r.err);
  const write = performance.now() - start;
  const { page, loadMs, close } = await open(html);
  const inPage = await page.evaluate(() => window.kinegen.loadMs);
  const kept = await page.evaluate(() => window.kinegen.run.n);
  // Slider moves to random rows: the handler alone, and until the next frame is drawn.
  const scrub = await page.evaluate(async () => {
    const s = document.getElementById('kg-slider'), n = +s.max + 1, handler = [], frame = [];
    for (let i = 0; i < 100; i++) {
      s.value = Math.floor(Math.random() * n);
      const a = performance.now();
      s.dispatchEvent(new Event('input'));
      handler.push(performance.now() - a);
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)));
      frame.push(performance.now() - a);
    }
    const q = (a, f) => a.sort((x, y) => x - y)[Math.floor(f * (a.length - 1))];
    return { handler: q(handler, 0.5), handler95: q(handler, 0.95), frame: q(frame, 0.5),
             frame95: q(frame, 0.95) };
  });
  await close();
  rows.push([n, (fs.statSync(csv).size / 2 ** 20).toFixed(1), kept,
             (fs.statSync(html).size / 2 ** 20).toFixed(1), ms(write), ms(loadMs), ms(inPage),
             scrub.handler.toFixed(2) + ' / ' + scrub.handler95.toFixed(2),
             ms(scrub.frame) + ' / ' + ms(scrub.frame95)]);
  fs.rmSync(csv);
}
console.log('| rows | CSV MiB | rows kept | page MiB | kinegen view ms | open ms (load to ready) |' +
            ' in page ms (navigation to ready) | scrub handler ms (median / 95%) |' +
            ' scrub to next frame ms (median / 95%) |');
console.log('|' + ' --- |'.repeat(9));
for (const r of rows) console.log('| ' + r.join(' | ') + ' |');
