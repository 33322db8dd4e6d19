// kinegen view, a spatial run (space: 3d): the mechanism in 3D with three.js, in a perspective
// view the mouse turns (left button), pans (right) and zooms (wheel) about its target
// (OrbitControls). Axes as the file's: x forward (red), y left (green), z up (blue); a grid in
// the plane z = 0. Each body is a group placed at every row by its 7 coordinates (origin and
// Euler parameters, three's quaternion (e1, e2, e3, e0)); in it, rods join the points where
// its joints and named points attach, and the joints are drawn where they are: a ball at a
// spherical or universal joint, a short cylinder along a revolute's or cylindrical's axis, a
// rail along a translational's. Named points are small red balls with their traced paths;
// named vectors are arrows from their body's origin. Only this file's code reads three.
(function () {
  'use strict';
  const kColours = { body: 0x4a6fa5, ground: 0x555555, ball: 0xe0a020, revolute: 0x2ca02c,
                     rail: 0x888888, point: 0xd62728, vector: 0x9467bd, link: 0x8c564b };
  const kPathRows = 2000;  // traced paths and extents: at most this many rows each

  // three and OrbitControls, from the page's own text of their modules (ES modules import one
  // another by URL: each gets a blob: URL, and the imports are pointed at them).
  async function loadThree() {
    const text = (id) => document.getElementById(id).textContent;
    const url = (code) => URL.createObjectURL(new Blob([code], { type: 'text/javascript' }));
    const core = url(text('kg-three-core'));
    const module = url(text('kg-three-module').split('"./three.core.min.js"')
      .join(JSON.stringify(core)));
    const orbit = text('kg-three-orbit');
    if (!orbit.includes("from 'three';")) throw new Error('OrbitControls: its import of three not found');
    const controls = url(orbit.replace("from 'three';", 'from ' + JSON.stringify(module) + ';'));
    const THREE = await import(module);
    const { OrbitControls } = await import(controls);
    return { THREE, OrbitControls };
  }

  // A point of body b (or ground, -1) at the positions q: r + A(p) s.
  function world(q, b, s) {
    if (b < 0) return [s[0], s[1], s[2]];
    const o = 7 * b, e0 = q[o + 3], e1 = q[o + 4], e2 = q[o + 5], e3 = q[o + 6];
    const ee = e1 * s[0] + e2 * s[1] + e3 * s[2], d = e0 * e0 - e1 * e1 - e2 * e2 - e3 * e3;
    return [q[o] + d * s[0] + 2 * e1 * ee + 2 * e0 * (e2 * s[2] - e3 * s[1]),
            q[o + 1] + d * s[1] + 2 * e2 * ee + 2 * e0 * (e3 * s[0] - e1 * s[2]),
            q[o + 2] + d * s[2] + 2 * e3 * ee + 2 * e0 * (e1 * s[1] - e2 * s[0])];
  }

  class SpaceDrawing {
    constructor(data, box, three) {
      this.data = data;
      this.scene3 = data.scene;
      this.THREE = three.THREE;
      this.OrbitControls = three.OrbitControls;
      this.box = box;
      this.width = Math.max(480, Math.min(800, window.innerWidth - 460));
      this.height = Math.round(this.width * 0.75);
      this.svg = null;  // no SVG: the page's hover is this drawing's own (hover())
    }

    // Every place a body is drawn from: its joints' points, its named points, its origin.
    attachments() {
      const s = this.scene3, per = s.bodies.map(() => []), ground = [];
      const add = (b, p) => {
        const list = b < 0 ? ground : per[b];
        if (!p || list.some((x) => Math.hypot(x[0] - p[0], x[1] - p[1], x[2] - p[2]) < 1e-9)) return;
        list.push(p);
      };
      for (const c of s.joints.concat(s.drivers)) {
        add(c.i, c.keys.si || c.keys.s);
        add(c.j, c.keys.sj);
      }
      for (const p of s.points) add(p.body, p.s);
      return { per, ground };
    }

    build(run, stride) {
      const THREE = this.THREE, s = this.scene3;
      this.run = run;
      const renderer = new THREE.WebGLRenderer({ antialias: true });
      renderer.setPixelRatio(window.devicePixelRatio || 1);
      renderer.setSize(this.width, this.height);
      this.box.appendChild(renderer.domElement);
      this.renderer = renderer;
      const scene = new THREE.Scene();
      scene.background = new THREE.Color(0xffffff);
      scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.2));
      const sun = new THREE.DirectionalLight(0xffffff, 1.6);
      sun.position.set(2, -1, 3);
      scene.add(sun);
      this.scene = scene;
      const { per, ground } = this.attachments();
      // The extent of the motion: every attachment over the run (at most kPathRows rows).
      const every = Math.max(1, Math.ceil(run.n / kPathRows));
      const K = window.KinegenDrawing, box3 = new THREE.Box3();
      for (let r = 0; r < run.n; r += every) {
        const q = K.rowQ(run, r);
        per.forEach((list, b) => {
          box3.expandByPoint(new THREE.Vector3(q[7 * b], q[7 * b + 1], q[7 * b + 2]));
          for (const p of list) box3.expandByPoint(new THREE.Vector3(...world(q, b, p)));
        });
      }
      for (const p of ground) box3.expandByPoint(new THREE.Vector3(...p));
      box3.expandByPoint(new THREE.Vector3(0, 0, 0));
      const size = Math.max(box3.getSize(new THREE.Vector3()).length(), 1e-6);
      this.size = size;
      const r = 0.012 * size;  // rods' radius; balls and joints scale with it
      this.radius = r;
      this.grid(size, box3);
      // Bodies: a group each, placed per row; ground is the scene.
      this.groups = s.bodies.map((b, k) => {
        const g = new THREE.Group();
        g.name = b.name;
        g.userData = { kind: 'body', index: k };
        scene.add(g);
        return g;
      });
      const groupOf = (b) => (b < 0 ? scene : this.groups[b]);
      per.forEach((list, b) => this.rods(this.groups[b], list, kColours.body, 'body', b));
      for (const p of ground) {
        const block = new THREE.Mesh(new THREE.BoxGeometry(3 * r, 3 * r, 3 * r),
                                     new THREE.MeshPhongMaterial({ color: kColours.ground }));
        block.position.set(...p);
        scene.add(block);
      }
      for (const b of this.groups) b.add(new THREE.AxesHelper(4 * r));
      this.links = [];
      s.joints.concat(s.drivers).forEach((c, k) => this.joint(c, k, groupOf, run, every));
      this.pointMeshes = {};
      s.points.forEach((p, k) => {
        const m = new THREE.Mesh(new THREE.SphereGeometry(1.3 * r, 16, 12),
                                 new THREE.MeshPhongMaterial({ color: kColours.point }));
        m.position.set(...p.s);
        m.name = p.name;
        m.userData = { kind: 'point', index: k };
        groupOf(p.body).add(m);
        this.pointMeshes[p.name] = m;
        this.path(run, every, p.body, p.s);
      });
      const longest = Math.max(1e-300, ...s.vectors.map((v) => Math.hypot(...v.v)));
      for (const v of s.vectors) {
        const length = Math.hypot(...v.v);
        if (!(length > 0)) continue;
        const arrow = new THREE.ArrowHelper(new THREE.Vector3(...v.v).normalize(),
                                            new THREE.Vector3(0, 0, 0),
                                            0.2 * size * length / longest, kColours.vector);
        arrow.name = v.name;
        groupOf(v.body).add(arrow);
      }
      this.camera = new THREE.PerspectiveCamera(40, this.width / this.height, size * 1e-3,
                                                size * 100);
      this.camera.up.set(0, 0, 1);
      const centre = box3.getCenter(new THREE.Vector3());
      this.camera.position.copy(centre).add(new THREE.Vector3(0.95, -1.15, 0.7).multiplyScalar(size));
      this.controls = new this.OrbitControls(this.camera, renderer.domElement);
      this.controls.target.copy(centre);
      this.controls.update();
      this.controls.addEventListener('change', () => this.render());
      this.hover();
    }

    // The ground grid (z = 0, lines a round step apart) and the axes, labelled.
    grid(size, box3) {
      const THREE = this.THREE;
      const step = Math.pow(10, Math.floor(Math.log10(size / 4)));
      const half = Math.ceil(Math.max(Math.abs(box3.min.x), Math.abs(box3.max.x),
                                      Math.abs(box3.min.y), Math.abs(box3.max.y), size / 2) / step);
      const grid = new THREE.GridHelper(2 * half * step, 2 * half, 0xbbbbbb, 0xe2e2e2);
      grid.rotation.x = Math.PI / 2;  // three's grid lies in x-z; the ground here is x-y
      this.scene.add(grid);
      const axes = new THREE.AxesHelper(0.35 * size);
      this.scene.add(axes);
      ['x', 'y', 'z'].forEach((name, k) => {
        const canvas = document.createElement('canvas');
        canvas.width = canvas.height = 64;
        const g = canvas.getContext('2d');
        g.font = 'bold 44px sans-serif';
        g.fillStyle = ['#d62728', '#2ca02c', '#1f4fd6'][k];
        g.textAlign = 'center';
        g.textBaseline = 'middle';
        g.fillText(name, 32, 34);
        const sprite = new THREE.Sprite(new THREE.SpriteMaterial({
          map: new THREE.CanvasTexture(canvas), depthTest: false }));
        const at = [0, 0, 0];
        at[k] = 0.4 * size;
        sprite.position.set(...at);
        sprite.scale.set(0.05 * size, 0.05 * size, 1);
        this.scene.add(sprite);
      });
    }

    // A rod (a cylinder) from a to b in `parent`'s frame.
    rod(parent, a, b, radius, colour) {
      const THREE = this.THREE;
      const mesh = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 12),
                                  new THREE.MeshPhongMaterial({ color: colour }));
      this.place(mesh, a, b, radius);
      parent.add(mesh);
      return mesh;
    }
    place(mesh, a, b, radius) {
      const THREE = this.THREE;
      const from = new THREE.Vector3(...a), d = new THREE.Vector3(...b).sub(from);
      const length = d.length();
      mesh.visible = length > 0;
      if (!(length > 0)) return;
      mesh.position.copy(from).addScaledVector(d, 0.5);
      mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), d.multiplyScalar(1 / length));
      mesh.scale.set(radius, length, radius);
    }

    // A body's rods: each attachment joined to the next, the last to the first when more than
    // two (a frame of its points), and a small block where it has a single point.
    rods(group, list, colour, kind, index) {
      const THREE = this.THREE, r = this.radius;
      if (list.length === 1) {
        const m = new THREE.Mesh(new THREE.BoxGeometry(4 * r, 4 * r, 4 * r),
                                 new THREE.MeshPhongMaterial({ color: colour }));
        m.position.set(...list[0]);
        m.userData = { kind, index };
        group.add(m);
      }
      for (let k = 0; k + 1 < list.length + (list.length > 2 ? 1 : 0); k++) {
        const m = this.rod(group, list[k], list[(k + 1) % list.length], r, colour);
        m.userData = { kind, index };
      }
    }

    // A joint where it is: a ball, a short cylinder along its axis, a rail, or a link whose
    // ends move (a distance joint), updated per row.
    joint(c, k, groupOf, run, every) {
      const THREE = this.THREE, r = this.radius, t = c.type, keys = c.keys;
      const tag = (m) => { m.userData = { kind: 'joint', index: k, name: c.name }; return m; };
      const at = keys.si || keys.s;
      if (!at) return;
      if (t === 'spherical' || t === 'universal') {
        const ball = tag(new THREE.Mesh(new THREE.SphereGeometry(2 * r, 20, 14),
                                        new THREE.MeshPhongMaterial({ color: kColours.ball })));
        ball.position.set(...at);
        groupOf(c.i).add(ball);
      } else if ((t === 'revolute' || t === 'cylindrical') && keys.axis_i) {
        const a = new THREE.Vector3(...keys.axis_i).normalize().multiplyScalar(4 * r);
        const p = new THREE.Vector3(...at);
        tag(this.rod(groupOf(c.i), p.clone().sub(a).toArray(), p.clone().add(a).toArray(),
                     1.8 * r, kColours.revolute));
      } else if (t === 'translational' && keys.axis_i) {
        // A rail along the axis, over the travel of sj along it in the run (and a margin).
        const axis = new THREE.Vector3(...keys.axis_i).normalize(), p = new THREE.Vector3(...at);
        let lo = 0, hi = 0;
        const K = window.KinegenDrawing;
        for (let row = 0; row < run.n; row += every) {
          const q = K.rowQ(run, row);
          const w = new THREE.Vector3(...world(q, c.j, keys.sj || [0, 0, 0]));
          const local = c.i < 0 ? w : this.toLocal(q, c.i, w);
          const u = local.sub(p).dot(axis);
          lo = Math.min(lo, u);
          hi = Math.max(hi, u);
        }
        const margin = 0.1 * (hi - lo) + 3 * r;
        tag(this.rod(groupOf(c.i), p.clone().addScaledVector(axis, lo - margin).toArray(),
                     p.clone().addScaledVector(axis, hi + margin).toArray(), 0.6 * r,
                     kColours.rail));
      } else if (t === 'distance' && keys.sj) {
        const m = tag(this.rod(this.scene, [0, 0, 0], [0, 0, 1], 0.8 * r, kColours.link));
        this.links.push({ mesh: m, c });
      }
    }
    toLocal(q, b, w) {
      const THREE = this.THREE, o = 7 * b;
      const quaternion = new THREE.Quaternion(q[o + 4], q[o + 5], q[o + 6], q[o + 3]);
      return w.clone().sub(new THREE.Vector3(q[o], q[o + 1], q[o + 2]))
        .applyQuaternion(quaternion.invert());
    }

    // The traced path of a point of body b over the run.
    path(run, every, b, s) {
      if (b < 0) return;
      const THREE = this.THREE, K = window.KinegenDrawing, xyz = [];
      for (let row = 0; row < run.n; row += every) xyz.push(...world(K.rowQ(run, row), b, s));
      xyz.push(...world(K.rowQ(run, run.n - 1), b, s));
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.Float32BufferAttribute(xyz, 3));
      this.scene.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0xe89090 })));
    }

    update(q, row) {
      this.row = row;
      this.groups.forEach((g, b) => {
        const o = 7 * b;
        g.position.set(q[o], q[o + 1], q[o + 2]);
        g.quaternion.set(q[o + 4], q[o + 5], q[o + 6], q[o + 3]);
      });
      for (const { mesh, c } of this.links)
        this.place(mesh, world(q, c.i, c.keys.si), world(q, c.j, c.keys.sj), 0.8 * this.radius);
      this.scene.updateMatrixWorld(true);
      this.render();
    }
    render() { this.renderer.render(this.scene, this.camera); }

    // Hover read-outs: the body, joint or point under the mouse, its name and its values now.
    hover() {
      const THREE = this.THREE, canvas = this.renderer.domElement, tip = document.getElementById('kg-tip');
      const ray = new THREE.Raycaster(), K = window.KinegenDrawing, s = this.scene3;
      canvas.addEventListener('pointermove', (e) => {
        const rect = canvas.getBoundingClientRect();
        ray.setFromCamera(new THREE.Vector2((e.clientX - rect.left) / rect.width * 2 - 1,
                                            -(e.clientY - rect.top) / rect.height * 2 + 1),
                          this.camera);
        const hit = ray.intersectObjects(this.scene.children, true)
          .find((h) => h.object.userData && h.object.userData.kind);
        if (!hit) { tip.hidden = true; return; }
        const { kind, index } = hit.object.userData;
        const item = kind === 'body' ? s.bodies[index] : kind === 'point' ? s.points[index]
          : s.joints.concat(s.drivers)[index];
        const lines = [kind + ': ' + item.name];
        for (const c of item.columns || [])
          lines.push(this.run.names[c] + ' = ' + K.fmt(this.run.column(c)[this.row]));
        tip.textContent = lines.join('\n');
        tip.hidden = false;
        tip.style.left = (e.clientX + 14) + 'px';
        tip.style.top = (e.clientY + 14) + 'px';
      });
      canvas.addEventListener('pointerleave', () => { tip.hidden = true; });
    }
  }

  async function create(data, box) {
    const three = await loadThree();
    const drawing = new SpaceDrawing(data, box, three);
    const footer = document.querySelector('footer').lastChild;
    footer.textContent = footer.textContent.replace(/\.\s*$/, '') + '; 3D by three.js r' +
        three.THREE.REVISION + ' (MIT licence, in this page\'s source).';
    return drawing;
  }

  window.KinegenSpace = { create, world };
})();
