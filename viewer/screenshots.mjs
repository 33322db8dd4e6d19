// Screenshots of kinegen view's page for the README (docs/figures/view_*.png): the four-bar
// with a read-out under the mouse and a plot of the coupler point against the crank angle, the
// planetary train, and the simulated press with a flywheel: its crank speed, which drops at each
// forming stroke, beside the energy balance; the spatial slider-crank in 3D with its slider's x
// and crank pin plotted. Run by scripts/make_figures.sh when viewer/node_modules is there.
//   node viewer/screenshots.mjs [path/to/kinegen] [NAME ...]   (NAME: only those pictures)
import path from 'node:path';

import { kinegen, open, scratch, SOURCE, TURN } from './tests/support.mjs';

const exe = process.argv[2];
if (exe) process.env.KINEGEN_EXE = path.resolve(exe);
const dir = scratch('screenshots'), out = path.join(SOURCE, 'docs/figures');
const only = process.argv.slice(3);

async function shot(name, args, action) {
  if (only.length && !only.includes(name)) return;
  const html = path.join(dir, name + '.html');
  const r = kinegen('view', ...args, '-o', html);  // relative names: the page shows them
  if (r.code !== 0) throw new Error(r.err);
  const { page, close } = await open(html, { width: 1280, height: 800 });
  await action(page);
  await page.screenshot({ path: path.join(out, 'view_' + name + '.png'), fullPage: true });
  await close();
}

const slide = (page, k) => page.evaluate((k) => window.kinegen.setRow(k), k);

process.chdir(SOURCE);
await shot('four_bar', ['examples/four_bar.yaml', '--t0', '0', '--t1', TURN,
                        '--steps', '360'], async (page) => {
  await page.selectOption('#kg-x', { label: 'crank.phi' });
  await page.selectOption('#kg-y', [{ label: 'P.x' }, { label: 'P.y' }]);
  await page.click('#kg-add');
  await page.locator('.kg-plot .kg-close').nth(1).click();  // the default plot of the points
  await slide(page, 110);
  const box = await page.locator('#kinegen-drawing').boundingBox();
  const p = await page.$eval('circle[data-kind="point"][data-name="P"]',
                             (c) => [+c.getAttribute('cx'), +c.getAttribute('cy')]);
  await page.mouse.move(box.x + p[0], box.y + p[1]);
});
await shot('planetary', ['examples/gears/planetary.yaml', '--t0', '0',
                         '--t1', '4', '--steps', '240', '--width', '640'], async (page) => {
  await slide(page, 50);
});
await shot('spatial_slider_crank', ['tests/mechanisms/spatial_slider_crank.yaml', '--t0', '0',
                                   '--t1', String(Math.PI / 3), '--steps', '180'], async (page) => {
  await slide(page, 40);
});
const press = path.join(dir, 'press_flywheel.csv');
const skipPress = only.length && !only.includes('press_flywheel');
const run = skipPress ? { code: 0 }
  : kinegen('simulate', 'examples/dynamics/press_flywheel.yaml', '--t1', '6', '--steps', '600',
            '--forces', '-q', '-o', press);
if (run.code !== 0) throw new Error(run.err);
await shot('press_flywheel', ['examples/dynamics/press_flywheel.yaml', '--csv', press],
           async (page) => {
  await page.selectOption('#kg-x', { label: 't' });
  await page.selectOption('#kg-y', [{ label: 'crank.omega' }, { label: 'energy.balance' }]);
  await page.click('#kg-add');
  await slide(page, 420);
});
