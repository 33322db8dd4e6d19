// What the viewer's tests share: the kinegen command, CSV files, and headless Chromium driven
// by playwright-core (pinned in viewer/package-lock.json) with a fresh profile per page.
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import { chromium } from 'playwright-core';

const here = path.dirname(fileURLToPath(import.meta.url));
export const SOURCE = process.env.KINEGEN_SOURCE_DIR || path.resolve(here, '../..');
export const EXE = process.env.KINEGEN_EXE || path.join(SOURCE, 'build/codegen/kinegen');
export const CHROMIUM = process.env.KINEGEN_CHROMIUM || '/usr/bin/chromium';
export const TURN = '6.283185307179586';
// The flags the project starts Chromium with (tests/test_animate.cpp, scripts/make_figures.sh).
const FLAGS = ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
               '--disable-background-networking', '--disable-component-update', '--disable-sync',
               '--hide-scrollbars', '--force-device-scale-factor=1'];

export function scratch(name) {
  const base = process.env.KINEGEN_TEST_TMP || path.join(os.tmpdir(), 'kinegen-test');
  const dir = path.join(base, 'viewer', name);
  fs.rmSync(dir, { recursive: true, force: true });
  fs.mkdirSync(dir, { recursive: true });
  return dir;
}

export function kinegen(...args) {
  const r = spawnSync(EXE, args, { encoding: 'utf8', maxBuffer: 1 << 26 });
  if (r.error) throw r.error;
  return { code: r.status, out: r.stdout, err: r.stderr };
}

// A CSV as its header and its columns of numbers (Number: the double the text reads as).
export function readCsv(file) {
  const lines = fs.readFileSync(file, 'utf8').trimEnd().split('\n');
  const header = lines[0].split(',');
  const columns = header.map(() => []);
  for (let r = 1; r < lines.length; r++) {
    const f = lines[r].split(',');
    for (let c = 0; c < f.length; c++) columns[c].push(Number(f[c]));
  }
  const col = (name) => {
    const k = header.indexOf(name);
    if (k < 0) throw new Error(file + ' has no column ' + name);
    return columns[k];
  };
  return { header, columns, col, rows: lines.length - 1 };
}

// A page in a fresh Chromium, with what it logged and every request besides its own file.
export async function open(file, { width = 1400, height = 900 } = {}) {
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'kinegen-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM, headless: true, args: FLAGS, viewport: { width, height } });
  const url = pathToFileURL(file).href;
  const log = { console: [], errors: [], requests: [] };
  context.on('request', (r) => { if (r.url() !== url) log.requests.push(r.url()); });
  await context.route((u) => u.href !== url, (route) => route.abort());
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error' || m.type() === 'warning') log.console.push(m.type() + ': ' + m.text());
  });
  page.on('pageerror', (e) => log.errors.push(e.message));
  const start = performance.now();
  await page.goto(url, { timeout: 180000 });
  await page.waitForFunction(() => window.kinegen && window.kinegen.ready, null,
                             { timeout: 180000 });
  const loadMs = performance.now() - start;
  const close = async () => {
    await context.close();
    fs.rmSync(profile, { recursive: true, force: true });
  };
  return { page, log, loadMs, close };
}

// Moves the slider to kept row k as a person would (an input event) and waits for a frame.
export async function slide(page, k) {
  await page.evaluate(async (k) => {
    const s = document.getElementById('kg-slider');
    s.value = k;
    s.dispatchEvent(new Event('input', { bubbles: true }));
    await new Promise((r) => requestAnimationFrame(() => r()));
  }, k);
}

// What the page draws, read back from its DOM: the pixel map, circles by kind, outlines.
export async function drawn(page) {
  return page.evaluate(() => {
    const svg = document.getElementById('kinegen-drawing');
    const map = { scale: +svg.dataset.kinegenScale, x0: +svg.dataset.kinegenX0,
                  y0: +svg.dataset.kinegenY0 };
    const circles = (kind) => [...svg.querySelectorAll(`circle[data-kind="${kind}"]`)].map((c) =>
      ({ name: c.dataset.name, x: +c.getAttribute('cx'), y: +c.getAttribute('cy') }));
    const shapes = (kind) => [...svg.querySelectorAll(`[data-kind="${kind}"]`)]
      .filter((e) => e.getAttribute('points'))
      .map((e) => ({ name: e.dataset.name,
                     points: e.getAttribute('points').trim().split(/\s+/)
                       .map((p) => p.split(',').map(Number)) }));
    return { map, pins: circles('pin'), points: circles('point'), gears: circles('gear'),
             bodies: shapes('body'), sliders: shapes('slider'),
             width: +svg.getAttribute('width'), height: +svg.getAttribute('height') };
  });
}

export function toPixels(map, [x, y]) { return [map.x0 + map.scale * x, map.y0 - map.scale * y]; }

// Each plot's legend: label -> the text of its value.
export async function legends(page) {
  return page.evaluate(() => [...document.querySelectorAll('.kg-plot')].map((p) => {
    const out = {};
    for (const tr of p.querySelectorAll('.u-legend tr.u-series'))
      out[tr.querySelector('.u-label').textContent] = tr.querySelector('.u-value').textContent;
    return out;
  }));
}

export async function notes(page) {
  return page.evaluate(() => ({
    error: document.getElementById('kg-error').textContent,
    notes: [...document.querySelectorAll('.kg-note')].map((n) => n.textContent) }));
}
