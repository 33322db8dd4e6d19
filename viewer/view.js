// kinegen view, the page: the time slider, play/pause and speed; uPlot plots of any columns,
// their cursor linked to the slider both ways; hover read-outs of bodies, joints and points;
// for modes, a mode and an amplitude. Values shown are the run's own numbers (String(v): the
// shortest text that reads back as the same double); only drawing is decimated (the traced
// paths), never a value shown. window.kinegen is for tests and for the curious.
(function () {
  'use strict';
  const K = window.KinegenDrawing;
  const $ = (id) => document.getElementById(id);
  const kPathPoints = 4000;  // traced paths: at most this many points each
  const kPalette = ['#1f77b4', '#d62728', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b', '#e377c2',
                    '#7f7f7f', '#bcbd22', '#17becf'];

  let data, run, drawing, row = 0, playing = false, speed = 1, clock = 0, lastFrame = 0;
  let mode = 0, amplitude = 1, hovered = null, timeIncreases = false;
  const plots = [];

  function note(text) {
    const p = document.createElement('div');
    p.className = 'kg-note';
    p.textContent = text;
    $('kg-notes').appendChild(p);
  }

  function time() { return run.column(run.time); }
  function increasing(a) {
    for (let k = 1; k < a.length; k++) if (!(a[k] >= a[k - 1])) return false;
    return a.length > 1 && a[a.length - 1] > a[0];
  }

  // Whether a column may serve as x: increasing at 65 rows across it (addPlot checks all).
  function looksIncreasing(a) {
    const n = a.length, step = Math.max(1, Math.floor((n - 1) / 64));
    for (let k = step; k < n; k += step) if (!(a[k] > a[k - step])) return false;
    return n > 1 && a[n - 1] > a[0];
  }

  // The source row of kept row k (the CSV's numbering from 0, below the header).
  function sourceRow(k) {
    if (data.modes) return k;
    return k === run.n - 1 ? data.total_rows - 1 : k * data.stride;
  }

  function setRow(k, from) {
    row = Math.max(0, Math.min(run.n - 1, k | 0));
    const t = time()[row];
    const label = (data.modes ? 'phase = ' : 't = ') + K.short(t);
    drawing.update(K.rowQ(run, row), row, label);
    if (from !== 'slider') $('kg-slider').value = row;
    $('kg-time').textContent = label + '   row ' + sourceRow(row) +
        (data.modes ? ' of ' + (run.n - 1) : ' of ' + (data.total_rows - 1)) +
        (data.stride > 1 ? ' (kept: ' + row + ' of ' + (run.n - 1) + ')' : '');
    if (!playing || from !== 'play') clock = t;
    if (from !== 'plot') for (const p of plots) p.follow(row);
    if (hovered) tip(hovered);
  }

  // ---- Play: the run's own time, times the speed; a row index where t does not increase.
  function rowAt(t) {
    const a = time();
    let lo = 0, hi = a.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (a[mid] <= t) lo = mid; else hi = mid - 1;
    }
    return lo;
  }
  function frame(now) {
    if (!playing) return;
    const dt = Math.min(0.25, (now - lastFrame) / 1000) * speed;
    lastFrame = now;
    const a = time(), t0 = a[0], t1 = a[run.n - 1];
    if (data.modes || !timeIncreases) {
      // Modes: a period in 2 s at 1x; runs without increasing t: all rows in 4 s.
      const per = data.modes ? 2 : 4;
      clock = (clock + dt * (data.modes ? 1 / per : (run.n - 1) / per));
      const k = data.modes ? Math.round((clock % 1) * (run.n - 1)) : Math.floor(clock) % run.n;
      setRow(k, 'play');
    } else {
      clock += dt;
      if (clock > t1) clock = t0 + ((clock - t1) % (t1 - t0));
      setRow(rowAt(clock), 'play');
    }
    requestAnimationFrame(frame);
  }
  function play(on) {
    playing = on;
    $('kg-play').innerHTML = on ? '&#10074;&#10074; Pause' : '&#9654; Play';
    if (on) {
      if (data.modes) clock = row / (run.n - 1);
      else if (!timeIncreases) clock = row;
      lastFrame = performance.now();
      requestAnimationFrame(frame);
    }
  }

  // ---- Hover: what is under the mouse (a point over a pin, a pin over a body: each), with
  // its name and its values now.
  function describe(target) {
    const kind = target.getAttribute('data-kind'), k = +target.getAttribute('data-index');
    const s = data.scene;
    let lines = [kind + ': ' + target.getAttribute('data-name')];
    const columns = (list) => list.map((c) => run.names[c] + ' = ' + K.fmt(run.column(c)[row]));
    const at = (a) => {
      const w = drawing.world(K.rowQ(run, row), a.body, a.s);
      return 'at x = ' + K.fmt(w[0]) + ', y = ' + K.fmt(w[1]) + ' (from the positions)';
    };
    if (kind === 'body') lines = lines.concat(columns(s.bodies[k].columns));
    else if (kind === 'point') lines = lines.concat(columns(s.points[k].columns));
    else if (kind === 'reaction') lines = lines.concat(columns(s.reactions[k].columns));
    else if (kind === 'pin') {
      lines.push(at(s.pins[k]));
      for (const r of s.reactions)
        if (r.name === s.pins[k].name) lines = lines.concat(columns(r.columns));
    } else if (kind === 'gear') lines.push('centre ' + at(s.pitch_circles[k]));
    else if (kind === 'slider') lines.push(at(s.sliders[k]));
    else if (kind === 'spring') {
      const sp = s.springs[k];
      lines.push(sp.rotational ? 'about ' + at(sp.a) : 'from ' + at(sp.a) + '\nto ' + at(sp.b));
    } else if (kind === 'load') {
      lines.push((s.loads[k].torque ? 'about ' : 'onto the point ') + at(s.loads[k]));
    }
    return lines.join('\n');
  }
  function tip(targets) {
    const box = $('kg-tip');
    let text = targets.map(describe).join('\n\n');
    if (data.modes) text = '(mode ' + (mode + 1) + ', phase ' + K.short(time()[row]) + ')\n' + text;
    box.textContent = text;
    box.hidden = false;
  }
  function hookHover(svg) {
    svg.addEventListener('mousemove', (e) => {
      const found = document.elementsFromPoint(e.clientX, e.clientY)
        .filter((t) => t.hasAttribute && t.hasAttribute('data-hover')).slice(0, 3);
      const box = $('kg-tip');
      if (!found.length) {
        hovered = null;
        box.hidden = true;
        return;
      }
      hovered = found;
      tip(found);
      box.style.left = (e.clientX + 14) + 'px';
      box.style.top = (e.clientY + 14) + 'px';
    });
    svg.addEventListener('mouseleave', () => {
      hovered = null;
      $('kg-tip').hidden = true;
    });
  }

  // ---- Plots: uPlot over every kept row (uPlot thins only its drawing, per pixel).
  class Plot {
    constructor(xc, ycs) {
      this.xc = xc;
      this.ycs = ycs;
      // The slider's row, which the cursor shows until the mouse enters the plot (null then).
      this.pinned = row;
      const box = document.createElement('div');
      box.className = 'kg-plot';
      const close = document.createElement('button');
      close.className = 'kg-close';
      close.title = 'Remove this plot';
      close.innerHTML = '&times;';
      close.onclick = () => this.remove();
      box.appendChild(close);
      $('kg-plots').appendChild(box);
      this.box = box;
      const width = Math.max(320, $('kg-plots').clientWidth - 4);
      const opts = {
        width, height: 220,
        scales: { x: { time: false } },
        series: [{ label: run.names[xc], value: (u, v) => K.fmt(v) }].concat(ycs.map((c, i) => ({
          label: run.names[c], stroke: kPalette[i % kPalette.length], width: 1.5,
          value: (u, v) => K.fmt(v), points: { show: false } }))),
        cursor: {
          // From the slider: exactly its row, whatever row is nearest the pixel.
          dataIdx: (u, s, closest) => (this.pinned !== null ? this.pinned : closest),
          drag: { x: true, y: false },
        },
        legend: { live: true },
        hooks: { setCursor: [(u) => this.moved(u)], ready: [() => this.follow(row)] },
      };
      this.u = new uPlot(opts, this.data(), box);
      this.u.over.addEventListener('mouseenter', () => { this.pinned = null; });
      this.u.over.addEventListener('mouseleave', () => {
        requestAnimationFrame(() => this.follow(row));  // back to the slider's row
      });
      this.follow(row);
    }
    data() { return [this.xc].concat(this.ycs).map((c) => run.column(c)); }
    refresh() {
      this.u.setData(this.data());
      this.follow(row);
    }
    // The mouse moved the cursor: the slider (and the other plots) follow its row.
    moved(u) {
      if (this.pinned !== null) return;
      const idx = u.cursor.idx;
      if (idx !== null && idx !== undefined && u.cursor.left >= 0) {
        setRow(idx, 'plot');
        for (const p of plots) if (p !== this) p.follow(row);
      }
    }
    follow(k) {
      const u = this.u;
      if (!u) return;
      this.pinned = k;
      const x = run.column(this.xc)[k], y = run.column(this.ycs[0])[k];
      const left = u.valToPos(x, 'x'), top = Number.isFinite(y) ? u.valToPos(y, 'y') : 10;
      u.setCursor({ left: Number.isFinite(left) ? left : 0, top: Number.isFinite(top) ? top : 10 });
    }
    remove() {
      this.u.destroy();
      this.box.remove();
      plots.splice(plots.indexOf(this), 1);
    }
  }

  function addPlot(xc, ycs) {
    if (!ycs.length) return;
    if (!increasing(run.column(xc))) {
      K.showError('x must increase over the run to plot against it: ' + run.names[xc]);
      return;
    }
    plots.push(new Plot(xc, ycs));
  }

  // The x of the first plots: t, or a spatial run's wheel_travel where it has one that
  // increases (a suspension's outputs read best against the travel).
  function defaultX() {
    const travel = run.names.indexOf('wheel_travel');
    return data.space === '3d' && travel >= 0 && increasing(run.column(travel)) ? travel
      : run.time;
  }

  // A spatial run's first plots: the suspension's outputs where it has them, else the bodies'
  // x, y, z that change; and the named points'.
  function spacePlots(moves) {
    const x = defaultX(), find = (n) => run.names.indexOf(n);
    const suspension = ['toe', 'camber', 'caster', 'kpi', 'scrub_radius', 'trail',
                        'track_change'].map(find).filter((c) => c >= 0 && c !== x);
    if (suspension.length) addPlot(x, suspension);
    else addPlot(x, data.scene.bodies.flatMap((b) => ['.x', '.y', '.z'].map((s) => find(b.name + s)))
      .filter((c) => c >= 0 && moves(c)).slice(0, 8));
    addPlot(x, data.scene.points.flatMap((p) => ['.x', '.y', '.z'].map((s) => find(p.name + s)))
      .filter((c) => c >= 0).slice(0, 8));
  }

  // The first plots: the bodies' angles, and the named points' or the force columns.
  function defaultPlots() {
    const names = run.names, find = (n) => names.indexOf(n);
    const t = data.modes ? 0 : run.time;
    if (data.modes) {
      // The coordinates that move in the first mode (a slider's x, not its constant phi):
      // |dq| above 1e-9 of the largest, in file order.
      const shape = data.modes.shapes[0];
      const largest = shape.reduce((m, v) => Math.max(m, Math.abs(v)), 0);
      addPlot(t, run.coordinates.filter((c, i) => Math.abs(shape[i]) > 1e-9 * largest)
        .slice(0, 6));
      return;
    }
    // The bodies' angles that change; where none does (blocks on sliders), their x and y that do.
    const moves = (c) => {
      const a = run.column(c);
      for (let k = 1; k < a.length; k++) if (a[k] !== a[0]) return true;
      return false;
    };
    if (data.space === '3d') return spacePlots(moves);
    const of = (suffixes) => data.scene.bodies.flatMap((b) => suffixes.map((s) => find(b.name + s)))
      .filter((c) => c >= 0 && moves(c));
    const angles = of(['.phi']);
    addPlot(t, angles.length ? angles : of(['.x', '.y']).slice(0, 8));
    const forces = [];
    for (const r of data.scene.reactions) forces.push(r.fx, r.fy);
    const points = [];
    for (const p of data.scene.points)
      for (const s of ['.x', '.y']) if (find(p.name + s) >= 0) points.push(find(p.name + s));
    addPlot(t, (forces.length ? forces : points).slice(0, 8));
  }

  function plotForm() {
    const xs = $('kg-x'), ys = $('kg-y');
    run.names.forEach((name, c) => {
      const o = document.createElement('option');
      o.value = c;
      o.textContent = name;
      ys.appendChild(o);
      if (c === run.time || looksIncreasing(run.column(c))) xs.appendChild(o.cloneNode(true));
    });
    xs.value = defaultX();
    $('kg-filter').addEventListener('input', () => {
      const f = $('kg-filter').value.toLowerCase();
      for (const o of ys.options) o.hidden = f !== '' && !o.textContent.toLowerCase().includes(f);
    });
    $('kg-add').onclick = () => addPlot(+xs.value, [...ys.selectedOptions].map((o) => +o.value));
  }

  // ---- Modes: a mode and an amplitude change the run that is drawn and plotted.
  function modesForm() {
    $('kg-modes').hidden = false;
    const select = $('kg-mode');
    data.modes.frequencies.forEach((f, k) => {
      const o = document.createElement('option');
      o.value = k;
      o.textContent = (k + 1) + ': ' + K.short(f) + ' Hz';
      select.appendChild(o);
    });
    const rebuild = () => {
      run = K.modeRun(data, mode, amplitude, 120);
      drawing.tracePaths(run, 1);
      for (const p of plots) p.refresh();
      $('kg-frequency').textContent = 'f = ' + K.fmt(data.modes.frequencies[mode]) + ' Hz, ' +
          'omega = ' + K.fmt(2 * Math.PI * data.modes.frequencies[mode]) + ' rad/s';
      setRow(row);
    };
    select.onchange = () => { mode = +select.value; rebuild(); };
    $('kg-amplitude').oninput = () => { amplitude = +$('kg-amplitude').value; rebuild(); };
    rebuild();
  }

  async function main() {
    data = JSON.parse($('kinegen-data').textContent);
    document.title = data.mechanism + ' - kinegen view';
    $('kg-title').textContent = data.mechanism;
    $('kg-source').textContent = data.file + (data.modes ? ', modes from ' : ', run: ') + data.run;
    $('kg-version').textContent = data.kinegen;
    if (data.failure) note('The run stops early: ' + data.failure + ' The page shows the rows ' +
                           'before it.');
    for (const n of data.notes) note(n);
    run = data.modes ? K.modeRun(data, 0, 1, 120) : await K.csvRun(data);
    timeIncreases = increasing(time());
    if (!data.modes && data.stride > 1)
      note('A long run: ' + data.total_rows + ' rows, of which the page keeps one in ' +
           data.stride + ' and the last (' + run.n + ' rows). Each value shown is the run\'s own ' +
           'at that row; kinegen view --max-rows keeps more.');
    // A spatial run is drawn in 3D (space.js, with three.js: only spatial pages have them).
    drawing = data.space === '3d' ? await window.KinegenSpace.create(data, $('kg-drawing-box'))
      : new K.Drawing(data, $('kg-drawing-box'));
    drawing.build(run, Math.max(1, Math.ceil(run.n / kPathPoints)));
    if (drawing.svg) hookHover(drawing.svg);
    const slider = $('kg-slider');
    slider.max = run.n - 1;
    slider.addEventListener('input', () => setRow(+slider.value, 'slider'));
    $('kg-play').onclick = () => play(!playing);
    $('kg-speed').onchange = () => { speed = +$('kg-speed').value; };
    document.addEventListener('keydown', (e) => {
      if (e.key === ' ' && e.target.tagName !== 'INPUT' && e.target.tagName !== 'SELECT') {
        e.preventDefault();
        play(!playing);
      }
    });
    plotForm();
    setRow(0);
    defaultPlots();
    if (data.modes) modesForm();
    window.kinegen = { data, get run() { return run; }, get row() { return row; }, setRow,
                       plots, play, ready: true, loadMs: performance.now(),
                       space: data.space === '3d' ? drawing : undefined };
  }

  main().catch((e) => {
    K.showError('The page could not show this run: ' + (e && e.message ? e.message : e));
    window.kinegen = { ready: true, error: String(e && e.message ? e.message : e) };
  });
})();
