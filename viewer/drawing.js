// kinegen view, the run and the drawing: reads the run (#kinegen-data: JSON; #kinegen-values:
// the columns as base64 little-endian doubles) and draws the mechanism from the scene that
// kinegen animate's drawing gives (animate_drawing: bodies, joints, guides, gears, curves,
// points, reaction arrows), in animate's styles and colours and with its pixel map, so that a
// row looks as animate's frame of it. view.js puts the page together.
(function () {
  'use strict';
  const SVGNS = 'http://www.w3.org/2000/svg';
  const $ = (id) => document.getElementById(id);
  const fmt = (v) => (v === null || v === undefined || Number.isNaN(v) ? '-' : String(v));
  const short = (v) => (Number.isFinite(v) ? Number(v.toPrecision(4)).toString() : String(v));
  const px2 = (v) => (Math.abs(v) < 0.005 ? '0' : v.toFixed(2));

  function showError(message) {
    const box = $('kg-error');
    box.hidden = false;
    box.textContent += (box.textContent ? '\n' : '') + message;
  }
  window.addEventListener('error', (e) => showError('The page failed: ' + e.message));

  // ---- The run: columns by name, each a Float64Array of n rows.
  function base64(text) {
    text = text.trim();
    if (typeof Uint8Array.fromBase64 === 'function') return Uint8Array.fromBase64(text);
    const bin = atob(text), bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return bytes;
  }

  // The stored columns (view_page.cpp, pack): inflated, the 8 byte planes put back together,
  // and each column's 64-bit differences summed (in two 32-bit halves with their carry).
  async function unpack(text, count, rows) {
    if (count === 0) return new Float64Array(0);
    if (typeof DecompressionStream !== 'function')
      throw new Error('this browser cannot inflate the page\'s data (no DecompressionStream)');
    let planes;
    try {
      const stream = new Blob([base64(text)]).stream().pipeThrough(new DecompressionStream('deflate'));
      planes = new Uint8Array(await new Response(stream).arrayBuffer());
    } catch (e) {
      throw new Error('the page\'s data does not inflate (' + e.message + '): the file is cut ' +
                      'short or damaged');
    }
    if (planes.length !== 8 * count)
      throw new Error('the page holds ' + planes.length / 8 + ' values where ' + count +
                      ' were written: the file is cut short or damaged');
    const words = new Uint32Array(2 * count);
    const p = [0, 1, 2, 3, 4, 5, 6, 7].map((b) => planes.subarray(b * count, (b + 1) * count));
    let lo = 0, hi = 0;
    for (let k = 0; k < count; k++) {
      const dlo = (p[0][k] | p[1][k] << 8 | p[2][k] << 16 | p[3][k] << 24) >>> 0;
      const dhi = (p[4][k] | p[5][k] << 8 | p[6][k] << 16 | p[7][k] << 24) >>> 0;
      if (k % rows === 0) {
        lo = dlo;
        hi = dhi;
      } else {
        const sum = lo + dlo;
        lo = sum >>> 0;
        hi = (hi + dhi + (sum > 0xffffffff ? 1 : 0)) >>> 0;
      }
      words[2 * k] = lo;
      words[2 * k + 1] = hi;
    }
    return new Float64Array(words.buffer);
  }

  async function csvRun(data) {
    const n = data.rows;
    const stored = data.layout.filter((l) => typeof l === 'number').length;
    const values = await unpack($('kinegen-values').textContent, stored * n, n);
    const cache = [];
    const column = (k) => {
      if (!cache[k]) {
        const l = data.layout[k];
        cache[k] = typeof l === 'number' ? values.subarray(l * n, (l + 1) * n)
                                         : new Float64Array(n).fill(l.value);
      }
      return cache[k];
    };
    return { n, names: data.columns, column, time: data.time, coordinates: data.coordinates };
  }

  // A mode as a run: one period of q + a sin(2 pi phase) dq, in `frames` rows.
  function modeRun(data, mode, scale, frames) {
    const m = data.modes, nq = m.q.length, n = frames + 1;
    const cols = [new Float64Array(n)];
    for (let i = 0; i < nq; i++) cols.push(new Float64Array(n));
    const a = m.amplitudes[mode] * scale;
    for (let k = 0; k < n; k++) {
      const phase = k / frames, s = Math.sin(2 * Math.PI * phase);
      cols[0][k] = phase;
      for (let i = 0; i < nq; i++) cols[i + 1][k] = m.q[i] + a * s * m.shapes[mode][i];
    }
    const coordinates = [];
    for (let i = 0; i < nq; i++) coordinates.push(i + 1);
    return { n, names: ['phase'].concat(data.columns), column: (k) => cols[k], time: 0,
             coordinates };
  }

  // ---- The loads' symbols in pixels (y down), as animate_svg.cpp draws them: lists of strokes.
  const kZigWidth = 5, kSideBySide = 8, kZigs = 10, kArrowLength = 40, kHead = 9;
  const kTorqueRadius = 16, kBodyDisc = 11;
  function springStrokes(a, b, spring, damper) {
    const ab = [b[0] - a[0], b[1] - a[1]], len = Math.hypot(ab[0], ab[1]);
    const d = len > 1e-9 ? [ab[0] / len, ab[1] / len] : [1, 0], n = [-d[1], d[0]];
    const at = (u, off) => [a[0] + u * ab[0] + off * n[0], a[1] + u * ab[1] + off * n[1]];
    const out = [];
    const zigzag = (u0, u1, off) => {
      const z = [at(u0, off)];
      for (let k = 1; k < kZigs; k++)
        z.push(at(u0 + (u1 - u0) * k / kZigs, off + (k % 2 ? kZigWidth : -kZigWidth)));
      z.push(at(u1, off));
      return z;
    };
    const dashpot = (u0, u1, off) => {
      const c0 = u0 + 0.3 * (u1 - u0), c1 = u0 + 0.7 * (u1 - u0), p = u0 + 0.55 * (u1 - u0);
      out.push([at(u0, off), at(c0, off)]);
      out.push([at(c1, off + kZigWidth), at(c0, off + kZigWidth), at(c0, off - kZigWidth),
                at(c1, off - kZigWidth)]);
      out.push([at(p, off + 0.6 * kZigWidth), at(p, off - 0.6 * kZigWidth)]);
      out.push([at(p, off), at(u1, off)]);
    };
    if (spring && damper) {
      out.push([a, at(0.15, 0)]);
      out.push([at(0.15, kSideBySide), at(0.15, -kSideBySide)]);
      out.push(zigzag(0.15, 0.85, kSideBySide));
      dashpot(0.15, 0.85, -kSideBySide);
      out.push([at(0.85, kSideBySide), at(0.85, -kSideBySide)]);
      out.push([at(0.85, 0), b]);
    } else if (damper) {
      dashpot(0, 1, 0);
    } else {
      out.push([a].concat(zigzag(0.2, 0.8, 0), [b]));
    }
    return out;
  }
  function coilStrokes(c) {
    const spiral = [];
    for (let k = 0; k <= 40; k++) {
      const u = k / 40, angle = 5 * Math.PI * u;
      spiral.push([c[0] + (3 + 10 * u) * Math.cos(angle), c[1] - (3 + 10 * u) * Math.sin(angle)]);
    }
    return [spiral];
  }
  function forceStrokes(at, dir) {
    const len = Math.hypot(dir[0], dir[1]) || 1, d = [dir[0] / len, -dir[1] / len];
    const n = [-d[1], d[0]], base = [at[0] - kHead * d[0], at[1] - kHead * d[1]];
    return [[[at[0] - kArrowLength * d[0], at[1] - kArrowLength * d[1]], at],
            [[base[0] + 0.45 * kHead * n[0], base[1] + 0.45 * kHead * n[1]], at,
             [base[0] - 0.45 * kHead * n[0], base[1] - 0.45 * kHead * n[1]]]];
  }
  function torqueStrokes(c, sign) {
    const arc = [];
    for (let k = 0; k <= 24; k++) {
      const u = sign > 0 ? k / 24 : 1 - k / 24, angle = Math.PI * (-1 / 3 + 1.5 * u);
      arc.push([c[0] + kTorqueRadius * Math.cos(angle), c[1] - kTorqueRadius * Math.sin(angle)]);
    }
    const end = arc[arc.length - 1], prev = arc[arc.length - 2];
    const tl = Math.hypot(end[0] - prev[0], end[1] - prev[1]);
    const t = [(end[0] - prev[0]) / tl, (end[1] - prev[1]) / tl], n = [-t[1], t[0]];
    const base = [end[0] - kHead * t[0], end[1] - kHead * t[1]];
    return [arc, [[base[0] + 0.45 * kHead * n[0], base[1] + 0.45 * kHead * n[1]], end,
                  [base[0] - 0.45 * kHead * n[0], base[1] - 0.45 * kHead * n[1]]]];
  }
  function pathData(strokes) {
    const parts = [];
    for (const s of strokes) s.forEach((p, k) => parts.push((k ? 'L' : 'M') + px2(p[0]) + ',' + px2(p[1])));
    return parts.join(' ');
  }

  // ---- The drawing: the scene's pieces as SVG elements, moved to a row's positions.
  function el(parent, tag, attrs) {
    const e = document.createElementNS(SVGNS, tag);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    parent.appendChild(e);
    return e;
  }

  class Drawing {
    constructor(data, box) {
      const s = data.scene, v = s.view;
      this.scene = s;
      this.view = v;
      this.c = s.colours;
      const w = Math.round(v.width), h = Math.round(v.height);
      this.svg = el(box, 'svg', { width: w, height: h, viewBox: '0 0 ' + w + ' ' + h,
        id: 'kinegen-drawing', 'data-kinegen-scale': v.scale, 'data-kinegen-x0': v.x0,
        'data-kinegen-y0': v.y0 });
      el(this.svg, 'rect', { width: '100%', height: '100%', fill: this.c.background });
      this.title = el(this.svg, 'text', { x: px2(v.margin), y: px2(v.title * 0.7),
        'font-family': 'sans-serif', 'font-size': 14, fill: '#333333' });
      this.name = data.mechanism;
      this.updates = [];  // functions of q (Float64Array) that move an element
      this.q = null;
    }

    world(q, body, s) {
      if (body < 0) return s;
      const x = q[3 * body], y = q[3 * body + 1], phi = q[3 * body + 2];
      const c = Math.cos(phi), sn = Math.sin(phi);
      return [x + c * s[0] - sn * s[1], y + sn * s[0] + c * s[1]];
    }
    rotate(phi, s) {
      const c = Math.cos(phi), sn = Math.sin(phi);
      return [c * s[0] - sn * s[1], sn * s[0] + c * s[1]];
    }
    angle(q, body) { return body < 0 ? 0 : q[3 * body + 2]; }
    px(w) { return [this.view.x0 + this.view.scale * w[0], this.view.y0 - this.view.scale * w[1]]; }
    points(list) {
      return list.map((w) => { const p = this.px(w); return px2(p[0]) + ',' + px2(p[1]); }).join(' ');
    }
    hover(e, kind, index, name) {
      e.setAttribute('data-hover', kind);
      e.setAttribute('data-kind', kind);
      e.setAttribute('data-index', index);
      e.setAttribute('data-name', name);
      return e;
    }
    // An element whose `points` follow a function of q.
    shape(tag, attrs, fn) {
      const e = el(this.svg, tag, attrs);
      this.updates.push((q) => e.setAttribute('points', this.points(fn(q))));
      return e;
    }
    guideEnds(q, g, lo, hi) {
      const o = g.origin, d = g.dir;
      return [this.world(q, g.guide, [o[0] + lo * d[0], o[1] + lo * d[1]]),
              this.world(q, g.guide, [o[0] + hi * d[0], o[1] + hi * d[1]])];
    }

    build(run, pathRows) {
      const s = this.scene, c = this.c;
      const q0 = rowQ(run, 0);
      // Traced paths of the named points over the whole run (decimated: drawing only).
      this.paths = s.points.map(() => el(this.svg, 'polyline', { fill: 'none', stroke: c.path,
        'stroke-width': 1.5, 'stroke-dasharray': '4 3', 'data-kind': 'path' }));
      this.tracePaths(run, pathRows);
      // Guides: fixed ones once (with hatching), slots on moving bodies with them.
      const guideStyle = { fill: 'none', stroke: c.ground, 'stroke-width': 3,
                           'stroke-linecap': 'round' };
      s.sliders.forEach((g, k) => {
        const ends = (q) => this.guideEnds(q, g, g.travel[0], g.travel[1]);
        if (g.guide < 0) {
          this.hover(el(this.svg, 'polyline', Object.assign({ points: this.points(ends(q0)) },
                                                               guideStyle)), 'guide', k, g.name);
          this.hatch(ends(q0));
        } else {
          this.hover(this.shape('polyline', guideStyle, ends), 'guide', k, g.name);
        }
      });
      for (const g of s.ground_pivots) this.groundPivot(this.px(g));
      s.struts.forEach((st, k) => this.hover(this.shape('polyline', { fill: 'none',
        stroke: c.ground, 'stroke-width': 2, 'stroke-dasharray': '6 4' },
        (q) => [this.world(q, st.a.body, st.a.s), this.world(q, st.b.body, st.b.s)]),
        'strut', k, st.name));
      (s.springs || []).forEach((sp, k) => {
        const e = this.hover(el(this.svg, 'path', { fill: 'none', stroke: c.spring,
          'stroke-width': 1.8, 'stroke-linejoin': 'round' }), 'spring', k, sp.name);
        if (sp.rotational && !sp.spring) e.setAttribute('stroke-dasharray', '3 2');
        this.updates.push((q) => {
          const a = this.px(this.world(q, sp.a.body, sp.a.s));
          e.setAttribute('d', pathData(sp.rotational ? coilStrokes(a) : springStrokes(a,
            this.px(this.world(q, sp.b.body, sp.b.s)), sp.spring, sp.damper)));
        });
      });
      s.bodies.forEach((b, k) => this.body(b, k));
      s.pitch_circles.forEach((pc, k) => this.pitchCircle(pc, k));
      s.pitch_lines.forEach((l, k) => this.hover(this.shape('polyline', { fill: 'none',
        stroke: c.gear, 'stroke-width': 2, 'stroke-dasharray': '12 4 2 4' },
        (q) => this.guideEnds(q, l, l.travel[0], l.travel[1])), 'pitch_line', k, l.name));
      s.curves.forEach((cv, k) => this.hover(this.shape('polyline', { fill: 'none',
        stroke: c.gear, 'stroke-width': 2, 'stroke-linejoin': 'round' },
        (q) => cv.points.map((p) => this.world(q, cv.body, p))), 'curve', k, cv.name));
      s.sliders.forEach((g, k) => this.hover(this.shape('polygon', { fill: c.slider,
        stroke: c.pin, 'stroke-width': 1.5 }, (q) => this.block(q, g)), 'slider', k, g.name));
      s.pins.forEach((p, k) => this.circle({ r: 5, fill: '#ffffff', stroke: c.pin,
        'stroke-width': 2 }, p, 'pin', k, p.name));
      s.welds.forEach((wd, k) => this.hover(this.shape('polygon', { fill: c.pin, stroke: c.pin,
        'stroke-width': 1 }, (q) => {
        const m = this.world(q, wd.body, wd.s), h = 5 / this.view.scale;
        return [[m[0] - h, m[1] - h], [m[0] + h, m[1] - h], [m[0] + h, m[1] + h],
                [m[0] - h, m[1] + h]];
      }), 'weld', k, wd.name));
      this.reactions(run);
      (s.loads || []).forEach((l, k) => {
        const e = this.hover(el(this.svg, 'path', { fill: 'none', stroke: c.load,
          'stroke-width': 2.5, 'stroke-linejoin': 'round', 'stroke-linecap': 'round' }), 'load',
          k, l.name);
        this.updates.push((q) => {
          const at = this.px(this.world(q, l.body, l.s));
          e.setAttribute('d', pathData(l.torque ? torqueStrokes(at, l.dir[0])
                                                : forceStrokes(at, l.dir)));
        });
      });
      s.points.forEach((p, k) => {
        this.circle({ r: 3.5, fill: c.point }, p, 'point', k, p.name);
        const t = el(this.svg, 'text', { 'font-family': 'sans-serif', 'font-size': 13,
          fill: c.point, stroke: '#ffffff', 'stroke-width': 3, 'paint-order': 'stroke',
          'data-kind': 'label' });
        t.textContent = p.name;
        this.updates.push((q) => {
          const at = this.px(this.world(q, p.body, p.s));
          t.setAttribute('x', px2(at[0] + 6));
          t.setAttribute('y', px2(at[1] - 6));
        });
      });
    }

    tracePaths(run, stride) {
      this.scene.points.forEach((p, k) => {
        const pts = [];
        for (let r = 0; r < run.n; r += stride) pts.push(this.world(rowQ(run, r), p.body, p.s));
        pts.push(this.world(rowQ(run, run.n - 1), p.body, p.s));
        this.paths[k].setAttribute('points', this.points(pts));
      });
    }

    hatch(ends) {
      const a = this.px(ends[0]), b = this.px(ends[1]);
      const len = Math.hypot(b[0] - a[0], b[1] - a[1]) || 1;
      const d = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
      let n = [-d[1], d[0]];
      if (n[1] < 0) n = [-n[0], -n[1]];
      const count = Math.max(2, Math.floor(len / 12));
      for (let k = 0; k <= count; k++) {
        const p = [a[0] + (b[0] - a[0]) * k / count, a[1] + (b[1] - a[1]) * k / count];
        el(this.svg, 'line', { x1: px2(p[0]), y1: px2(p[1]), x2: px2(p[0] + 8 * n[0] - 6 * d[0]),
          y2: px2(p[1] + 8 * n[1] - 6 * d[1]), stroke: this.c.ground, 'stroke-width': 1 });
      }
    }

    groundPivot(p) {
      el(this.svg, 'polygon', { fill: '#dddddd', stroke: this.c.ground, 'stroke-width': 1.5,
        points: [p, [p[0] - 10, p[1] + 16], [p[0] + 10, p[1] + 16]]
          .map((x) => px2(x[0]) + ',' + px2(x[1])).join(' '), 'data-kind': 'ground' });
      for (let k = 0; k < 5; k++) {
        const x = p[0] - 12 + 6 * k;
        el(this.svg, 'line', { x1: px2(x), y1: px2(p[1] + 16), x2: px2(x - 5), y2: px2(p[1] + 22),
          stroke: this.c.ground, 'stroke-width': 1 });
      }
    }

    body(b, k) {
      const c = this.c, pts = b.outline;
      const outline = (q) => pts.map((s) => this.world(q, k, s));
      if (pts.length === 1) {
        // A disc about its one point, wider than a pin, and a radius along its x axis that
        // shows its rotation (as animate draws it).
        this.circle({ r: kBodyDisc, fill: c.link, 'fill-opacity': 0.35, stroke: c.link,
                      'stroke-width': 3 }, { body: k, s: pts[0] }, 'body', k, b.name);
        this.shape('polyline', { fill: 'none', stroke: c.link, 'stroke-width': 3,
          'stroke-linecap': 'round', 'data-kind': 'body-mark' }, (q) => {
          const m = this.world(q, k, pts[0]), r = this.rotate(this.angle(q, k),
                                                                [kBodyDisc / this.view.scale, 0]);
          return [m, [m[0] + r[0], m[1] + r[1]]];
        });
        return;
      }
      const style = { stroke: c.link, 'stroke-width': 8, 'stroke-linejoin': 'round',
                      'stroke-linecap': 'round' };
      if (pts.length === 2) style.fill = 'none';
      else Object.assign(style, { fill: c.link, 'fill-opacity': 0.2 });
      this.hover(this.shape(pts.length === 2 ? 'polyline' : 'polygon', style, outline), 'body', k,
                 b.name);
    }

    pitchCircle(pc, k) {
      const e = this.circle({ r: px2(pc.radius * this.view.scale), fill: 'none', stroke: this.c.gear,
        'stroke-width': 2 }, pc, 'gear', k, pc.name);
      e.setAttribute('data-hover', 'gear');
      this.shape('polyline', { fill: 'none', stroke: this.c.gear, 'stroke-width': 2,
        'stroke-linecap': 'round' }, (q) => {
        const m = this.world(q, pc.body, pc.s), r = this.rotate(this.angle(q, pc.body), [pc.radius, 0]);
        return [m, [m[0] + r[0], m[1] + r[1]]];
      });
    }

    block(q, g) {
      const m = this.world(q, g.body, g.s);
      const d0 = this.rotate(this.angle(q, g.guide), g.dir), f = 15 / this.view.scale;
      const d = [d0[0] * f, d0[1] * f], n = [-d[1] * 0.55, d[0] * 0.55];
      return [[m[0] - d[0] - n[0], m[1] - d[1] - n[1]], [m[0] + d[0] - n[0], m[1] + d[1] - n[1]],
              [m[0] + d[0] + n[0], m[1] + d[1] + n[1]], [m[0] - d[0] + n[0], m[1] - d[1] + n[1]]];
    }

    circle(attrs, at, kind, index, name) {
      const e = this.hover(el(this.svg, 'circle', attrs), kind, index, name);
      this.updates.push((q) => {
        const p = this.px(this.world(q, at.body, at.s));
        e.setAttribute('cx', px2(p[0]));
        e.setAttribute('cy', px2(p[1]));
      });
      return e;
    }

    // Arrows of J.fx, J.fy from each joint's point, to one scale for the run (animate --forces).
    reactions(run) {
      const s = this.scene, v = this.view;
      if (!s.reactions.length) return;
      let largest = 0;
      for (const r of s.reactions) {
        const fx = run.column(r.fx), fy = run.column(r.fy);
        for (let k = 0; k < run.n; k++) {
          const f = Math.hypot(fx[k], fy[k]);
          if (f > largest) largest = f;
        }
      }
      const longest = 0.25 * Math.min(Math.round(v.width), Math.round(v.height) - v.title);
      const per = largest > 0 ? longest / largest : 0;
      s.reactions.forEach((r, k) => {
        const e = this.hover(el(this.svg, 'polyline', { fill: this.c.force, stroke: this.c.force,
          'stroke-width': 2.5, 'stroke-linejoin': 'round' }), 'reaction', k, r.name);
        const fx = run.column(r.fx), fy = run.column(r.fy);
        this.updates.push((q, row) => {
          const tail = this.px(this.world(q, r.body, r.s));
          const tip = [tail[0] + per * fx[row], tail[1] - per * fy[row]];
          const len = Math.hypot(tip[0] - tail[0], tip[1] - tail[1]);
          const d = len > 0 ? [(tip[0] - tail[0]) / len, (tip[1] - tail[1]) / len] : [1, 0];
          const n = [-d[1], d[0]], head = Math.min(9, 0.4 * len);
          const base = [tip[0] - head * d[0], tip[1] - head * d[1]];
          const pts = [tail, base, [base[0] + 0.45 * head * n[0], base[1] + 0.45 * head * n[1]], tip,
                       [base[0] - 0.45 * head * n[0], base[1] - 0.45 * head * n[1]], base];
          e.setAttribute('points', pts.map((p) => px2(p[0]) + ',' + px2(p[1])).join(' '));
        });
      });
      const caption = el(this.svg, 'text', { x: px2(v.margin), y: px2(v.height - 8),
        'font-family': 'sans-serif', 'font-size': 12, fill: this.c.force });
      caption.textContent = 'reactions: the longest arrow is ' + short(largest);
    }

    update(q, row, label) {
      for (const u of this.updates) u(q, row);
      this.title.textContent = this.name + '   ' + label;
    }
  }

  // The positions of row k (coordinate_labels order).
  const qScratch = { run: null, q: null };
  function rowQ(run, k) {
    if (qScratch.run !== run) {
      qScratch.run = run;
      qScratch.q = new Float64Array(run.coordinates.length);
    }
    const q = qScratch.q;
    for (let i = 0; i < q.length; i++) q[i] = run.column(run.coordinates[i])[k];
    return q;
  }

  window.KinegenDrawing = { csvRun, modeRun, Drawing, rowQ, fmt, short, showError };
})();
