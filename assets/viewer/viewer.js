/* funcorr viewer: X and Y side by side in linked cameras (three.js r146, THREE global).
 * The page is written by funcorr (src/viz/html.rs): metadata in #funcorr-meta (JSON), every
 * array in #funcorr-bN (base64 of little-endian float32 / uint32 / uint8). Colours are computed
 * by funcorr; this script only draws, picks and reports. window.funcorr is its interface for
 * tests and scripts (see the end of the file). */
(function () {
  'use strict';
  const $ = (id) => document.getElementById(id);
  const meta = JSON.parse($('funcorr-meta').textContent);
  const hook = { meta, frames: 0, loadMs: null, errors: [] };
  let resolveReady;
  hook.ready = new Promise((r) => { resolveReady = r; });
  window.funcorr = hook;

  // ---- data -------------------------------------------------------------------------------
  const cache = new Map();
  function bytes(k) {
    if (cache.has(k)) return cache.get(k);
    const el = $('funcorr-b' + k);
    const s = el.textContent.trim();
    let u;
    if (typeof Uint8Array.fromBase64 === 'function') {
      u = Uint8Array.fromBase64(s);
    } else {
      const b = atob(s);
      u = new Uint8Array(b.length);
      for (let i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
    }
    el.textContent = '';
    cache.set(k, u);
    return u;
  }
  const f32 = (k) => { const u = bytes(k); return new Float32Array(u.buffer, u.byteOffset, u.byteLength >> 2); };
  const u32 = (k) => { const u = bytes(k); return new Uint32Array(u.buffer, u.byteOffset, u.byteLength >> 2); };
  const opt = (k, f) => (k === null || k === undefined ? null : f(k));

  const mapXY = opt(meta.map_xy, u32);
  const mapYX = opt(meta.map_yx, u32);
  const err = meta.errors ? { values: f32(meta.errors.values), measured: bytes(meta.errors.measured) } : null;
  const fields = new Map(meta.fields.map((f) => [f.id, { ...f, data: f32(f.values) }]));

  // ---- scene ------------------------------------------------------------------------------
  const canvas = $('view');
  const stage = $('stage');
  // Large pairs: no multisampling (a software renderer spends most of a frame on it), and a
  // preview of about 60,000 points per shape drawn while the camera moves (level of detail).
  const FACES = meta.x.faces + (meta.y ? meta.y.faces : 0);
  const VERTICES = meta.x.n + (meta.y ? meta.y.n : 0);
  const BIG = VERTICES > 600000;
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: FACES < 1000000 });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0xffffff, 1);
  renderer.setScissorTest(true);
  const LIGHT = new THREE.Vector3(-0.35, 0.45, 1).normalize(); // as the PNG renderer (camera frame)
  const neutral = new THREE.Color(meta.neutral[0] / 255, meta.neutral[1] / 255, meta.neutral[2] / 255);

  function makeShape(m, side) {
    const pos = f32(m.positions);
    const geom = new THREE.BufferGeometry();
    geom.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    const mesh = m.triangles !== null;
    if (mesh) geom.setIndex(new THREE.BufferAttribute(u32(m.triangles), 1));
    geom.computeBoundingSphere();
    const s = { side, meta: m, geom, pos, mesh, n: m.n, colorAttrs: new Map() };
    s.scene = new THREE.Scene();
    s.scene.add(new THREE.AmbientLight(0xffffff, 0.3));
    s.light = new THREE.DirectionalLight(0xffffff, 0.75);
    s.scene.add(s.light);
    s.group = new THREE.Group();
    s.scene.add(s.group);
    if (mesh) {
      const common = { vertexColors: true, side: THREE.DoubleSide, polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 };
      s.materials = {
        smooth: new THREE.MeshPhongMaterial({ ...common, specular: 0x000000, shininess: 0 }),
        flat: new THREE.MeshPhongMaterial({ ...common, specular: 0x000000, shininess: 0, flatShading: true }),
        unlit: new THREE.MeshBasicMaterial(common),
      };
      s.object = new THREE.Mesh(geom, s.materials.smooth);
      s.wire = null;
    } else {
      s.materials = { points: new THREE.PointsMaterial({ vertexColors: true, size: 1, sizeAttenuation: true }) };
      s.object = new THREE.Points(geom, s.materials.points);
    }
    s.group.add(s.object);
    if (BIG && mesh) {
      const step = Math.ceil(s.n / 60000);
      const idx = new Uint32Array(Math.ceil(s.n / step));
      for (let k = 0; k < idx.length; k++) idx[k] = k * step;
      s.proxyGeom = new THREE.BufferGeometry();
      s.proxyGeom.setAttribute('position', geom.getAttribute('position'));
      s.proxyGeom.setIndex(new THREE.BufferAttribute(idx, 1));
      s.materials.proxy = new THREE.PointsMaterial({ vertexColors: true, size: 1, sizeAttenuation: true });
      s.proxy = new THREE.Points(s.proxyGeom, s.materials.proxy);
      s.proxy.visible = false;
      s.group.add(s.proxy);
      s.proxyCount = idx.length;
    }
    s.marker = new THREE.Mesh(new THREE.SphereGeometry(1, 20, 14), new THREE.MeshBasicMaterial({ color: 0xff00ff }));
    s.marker.visible = false;
    s.group.add(s.marker);
    return s;
  }

  const X = makeShape(meta.x, 'x');
  const Y = meta.y ? makeShape(meta.y, 'y') : null;
  const shapes = Y ? [X, Y] : [X];
  // One scale for both (relative sizes kept), each centred on its bounding sphere.
  const R = Math.max(...shapes.map((s) => s.geom.boundingSphere.radius)) || 1;
  for (const s of shapes) {
    const c = s.geom.boundingSphere.center;
    s.object.scale.setScalar(1 / R);
    s.object.position.set(-c.x / R, -c.y / R, -c.z / R);
    s.object.updateMatrixWorld(true);
    s.marker.scale.setScalar(0.02);
    if (s.proxy) {
      s.proxy.scale.copy(s.object.scale);
      s.proxy.position.copy(s.object.position);
      s.materials.proxy.size = Math.max(0.004, 4.5 * (s.geom.boundingSphere.radius / R) / Math.sqrt(s.proxyCount));
    }
    if (!s.mesh) {
      // Point size: about the mean spacing of the points (area of the bounding sphere / n).
      const r = s.geom.boundingSphere.radius / R;
      s.materials.points.size = Math.max(0.004, 3.2 * r / Math.sqrt(s.n));
    }
  }

  const camera = new THREE.PerspectiveCamera(30, 1, 0.01, 100);
  const DIST = 1 / Math.sin(THREE.MathUtils.degToRad(15)) * 1.04;
  camera.position.set(0, 0, DIST);
  const controls = new THREE.OrbitControls(camera, canvas);
  controls.target.set(0, 0, 0);
  controls.update();
  controls.saveState();
  controls.addEventListener('change', () => requestRender());
  // Level of detail: the point preview while the camera moves, the full meshes once it rests.
  let lod = false, lodTimer = null;
  function setLod(on) {
    lod = on;
    for (const s of shapes) {
      if (!s.proxy) continue;
      s.proxy.visible = on;
      s.object.visible = !on;
      if (s.wire) s.wire.visible = !on && state.wireframe;
    }
  }
  if (BIG) {
    controls.addEventListener('start', () => { clearTimeout(lodTimer); setLod(true); });
    controls.addEventListener('end', () => {
      clearTimeout(lodTimer);
      lodTimer = setTimeout(() => { setLod(false); requestRender(); }, 200);
    });
  }

  // ---- state, colourings --------------------------------------------------------------------
  const state = { mode: meta.start || 'transfer', show: 'both', shading: 'smooth', wireframe: false, selected: null };
  const modeById = new Map(meta.modes.map((m) => [m.id, m]));

  function colorAttr(s, k) {
    if (!s.colorAttrs.has(k)) s.colorAttrs.set(k, new THREE.BufferAttribute(bytes(k), 3, true));
    return s.colorAttrs.get(k);
  }
  function applyMode() {
    const mode = modeById.get(state.mode);
    for (const s of shapes) {
      const k = mode[s.side];
      const colored = k !== null && k !== undefined;
      if (colored) {
        s.geom.setAttribute('color', colorAttr(s, k));
        if (s.proxyGeom) s.proxyGeom.setAttribute('color', colorAttr(s, k));
      }
      for (const mat of Object.values(s.materials)) {
        if (mat.vertexColors !== colored) { mat.vertexColors = colored; mat.needsUpdate = true; }
        mat.color.copy(colored ? new THREE.Color(1, 1, 1) : neutral);
      }
    }
    if (mode.mark) select(mode.mark.side, mode.mark.vertex, false);
    drawColorbar(mode.bar ? meta.bars[mode.bar] : null);
    requestRender();
  }
  function applyShading() {
    for (const s of shapes) {
      if (!s.mesh) continue;
      if (state.shading !== 'unlit' && !s.geom.getAttribute('normal')) s.geom.computeVertexNormals();
      s.object.material = s.materials[state.shading];
      if (state.wireframe && !s.wire) {
        s.wire = new THREE.Mesh(s.geom, new THREE.MeshBasicMaterial({ color: 0x222222, wireframe: true, transparent: true, opacity: 0.35 }));
        s.wire.position.copy(s.object.position);
        s.wire.scale.copy(s.object.scale);
        s.group.add(s.wire);
      }
      if (s.wire) s.wire.visible = state.wireframe && !lod;
    }
    requestRender();
  }

  function drawColorbar(bar) {
    const box = $('colorbar');
    if (!bar) { box.hidden = true; return; }
    box.hidden = false;
    box.innerHTML = '';
    const name = document.createElement('div');
    name.className = 'name';
    name.textContent = bar.label;
    const c = document.createElement('canvas');
    c.width = bar.colors.length;
    c.height = 1;
    const ctx = c.getContext('2d');
    const img = ctx.createImageData(bar.colors.length, 1);
    bar.colors.forEach((rgb, i) => { img.data.set([rgb[0], rgb[1], rgb[2], 255], 4 * i); });
    ctx.putImageData(img, 0, 0);
    c.style.imageRendering = 'pixelated';
    const ticks = document.createElement('div');
    ticks.className = 'ticks';
    for (const t of bar.ticks) {
      const sp = document.createElement('span');
      sp.style.left = (100 * (t - bar.min) / ((bar.max - bar.min) || 1)) + '%';
      sp.textContent = fmt(t) + (bar.over && t === bar.ticks[bar.ticks.length - 1] ? '+' : '');
      ticks.appendChild(sp);
    }
    box.append(name, c, ticks);
  }
  const fmt = (v) => (v === 0 ? '0' : Math.abs(v) >= 0.01 && Math.abs(v) < 1000 ? String(+v.toPrecision(3)) : v.toExponential(2));

  // ---- layout and drawing ------------------------------------------------------------------
  function layout() {
    const W = stage.clientWidth, H = stage.clientHeight;
    const shown = !Y || state.show === 'x' ? [X] : state.show === 'y' ? [Y] : [X, Y];
    const w = W / shown.length;
    return shown.map((s, k) => ({ s, x: k * w, y: 0, w, h: H }));
  }
  let size = [0, 0];
  function resize() {
    const W = stage.clientWidth, H = stage.clientHeight;
    if (W !== size[0] || H !== size[1]) {
      size = [W, H];
      renderer.setSize(W, H, false);
    }
  }
  function placeLabels(views) {
    const box = $('labels');
    box.innerHTML = '';
    for (const v of views) {
      const sp = document.createElement('span');
      sp.style.left = (v.x + 8) + 'px';
      const m = v.s.meta;
      sp.textContent = `${v.s.side.toUpperCase()}: ${m.name} (${m.n.toLocaleString('en')} ${m.triangles === null ? 'points' : 'vertices'})`;
      box.appendChild(sp);
    }
  }
  function render() {
    resize();
    const views = layout();
    const dir = LIGHT.clone().applyQuaternion(camera.quaternion);
    renderer.setScissorTest(false);
    renderer.clear();
    renderer.setScissorTest(true);
    for (const v of views) {
      renderer.setViewport(v.x, v.y, v.w, v.h);
      renderer.setScissor(v.x, v.y, v.w, v.h);
      camera.aspect = v.w / v.h;
      camera.updateProjectionMatrix();
      v.s.light.position.copy(dir).multiplyScalar(10);
      renderer.render(v.s.scene, camera);
    }
    placeLabels(views);
    hook.frames += 1;
  }
  let pending = false;
  let waiters = [];
  function requestRender() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      render();
      const w = waiters;
      waiters = [];
      // Resolved one frame later, once the drawn frame is on screen.
      requestAnimationFrame(() => w.forEach((f) => f()));
    });
  }
  const nextFrame = () => new Promise((r) => { waiters.push(r); requestRender(); });
  new ResizeObserver(() => requestRender()).observe(stage);

  // ---- picking, selection, hover ------------------------------------------------------------
  const raycaster = new THREE.Raycaster();
  function viewAt(cx, cy) {
    return layout().find((v) => cx >= v.x && cx < v.x + v.w && cy >= v.y && cy < v.y + v.h) || null;
  }
  function localVertex(s, i) {
    return new THREE.Vector3(s.pos[3 * i], s.pos[3 * i + 1], s.pos[3 * i + 2]);
  }
  function worldVertex(s, i) {
    return s.object.localToWorld(localVertex(s, i));
  }
  // The vertex under canvas point (cx, cy) in CSS pixels: { s, vertex, distance } or null.
  function pickAt(cx, cy) {
    const v = viewAt(cx, cy);
    if (!v) return null;
    camera.aspect = v.w / v.h;
    camera.updateProjectionMatrix();
    raycaster.setFromCamera(new THREE.Vector2(((cx - v.x) / v.w) * 2 - 1, -((cy - v.y) / v.h) * 2 + 1), camera);
    if (!v.s.mesh) raycaster.params.Points.threshold = v.s.materials.points.size;
    const hits = raycaster.intersectObject(v.s.object, false);
    if (!hits.length) return { s: v.s, vertex: null };
    const h = hits[0];
    let vertex = h.index;
    if (h.face) {
      const p = v.s.object.worldToLocal(h.point.clone());
      vertex = [h.face.a, h.face.b, h.face.c].reduce((best, k) =>
        localVertex(v.s, k).distanceToSquared(p) < localVertex(v.s, best).distanceToSquared(p) ? k : best);
    }
    return { s: v.s, vertex, distance: h.distance };
  }

  function describe(side, i) {
    let t = `${side.toUpperCase()} vertex ${i}`;
    if (side === 'x' && err) {
      t += ` · error ${err.values[i].toFixed(4)}` + (err.measured[i] ? '' : ' (nearest template point)');
    }
    const mode = modeById.get(state.mode);
    const f = fields.get(mode.id);
    if (f && f.side === side) t += ` · ${mode.label} = ${fmt(f.data[i])}`;
    return t;
  }
  function mark(s, i) {
    if (!s) return;
    if (i === null || i === undefined) { s.marker.visible = false; return; }
    s.marker.position.copy(worldVertex(s, i));
    s.marker.visible = true;
  }
  function select(side, i, announce = true) {
    let xi = null, yj = null;
    if (side === 'x') {
      xi = i;
      yj = mapXY ? mapXY[i] : null;
    } else {
      yj = i;
      xi = mapYX ? mapYX[i] : null;
    }
    mark(X, xi);
    mark(Y, yj);
    state.selected = { x: xi, y: yj, side };
    if (announce) {
      const parts = [];
      if (side === 'x') {
        parts.push(describe('x', xi));
        parts.push(yj === null ? 'no map to Y' : `→ ${describe('y', yj)}`);
      } else {
        parts.push(describe('y', yj));
        parts.push(xi === null ? 'no map Y → X' : `← ${describe('x', xi)}` + (meta.map_yx_inferred ? ' (nearest mapped vertex)' : ''));
      }
      $('status').textContent = parts.join(' ');
    }
    requestRender();
    return { x: xi, y: yj };
  }

  let down = null;
  canvas.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  canvas.addEventListener('pointerup', (e) => {
    if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4 || e.button !== 0) return;
    const r = canvas.getBoundingClientRect();
    const hit = pickAt(e.clientX - r.left, e.clientY - r.top);
    if (hit && hit.vertex !== null) select(hit.s.side, hit.vertex);
  });
  let hoverTimer = null;
  canvas.addEventListener('pointermove', (e) => {
    const tip = $('tip');
    tip.hidden = true;
    clearTimeout(hoverTimer);
    if (e.buttons) return;
    const r = canvas.getBoundingClientRect();
    const cx = e.clientX - r.left, cy = e.clientY - r.top;
    // Picking costs O(faces): wait until the pointer rests.
    hoverTimer = setTimeout(() => {
      const hit = pickAt(cx, cy);
      if (!hit || hit.vertex === null) return;
      tip.textContent = describe(hit.s.side, hit.vertex);
      tip.style.left = (cx + 14) + 'px';
      tip.style.top = (cy + 10) + 'px';
      tip.hidden = false;
    }, X.n + (Y ? Y.n : 0) > 400000 ? 250 : 60);
  });
  canvas.addEventListener('pointerleave', () => { clearTimeout(hoverTimer); $('tip').hidden = true; });

  // ---- camera ----------------------------------------------------------------------------
  // Azimuth and elevation in degrees, as `funcorr match --view` (0,0: looking along -Z, Y up).
  function setView(az, el) {
    const a = THREE.MathUtils.degToRad(az), e = THREE.MathUtils.degToRad(Math.max(-89.9, Math.min(89.9, el)));
    controls.reset();
    camera.position.set(DIST * Math.cos(e) * Math.sin(a), DIST * Math.sin(e), DIST * Math.cos(e) * Math.cos(a));
    camera.up.set(0, 1, 0);
    controls.update();
    requestRender();
  }

  // ---- controls and caption -------------------------------------------------------------
  function control(label, el) {
    const l = document.createElement('label');
    l.append(label + ' ', el);
    $('controls').appendChild(l);
    return el;
  }
  function selectEl(options, value, onchange) {
    const s = document.createElement('select');
    for (const [v, t] of options) s.add(new Option(t, v, false, v === value));
    s.addEventListener('change', () => onchange(s.value));
    return s;
  }
  function button(text, onclick) {
    const b = document.createElement('button');
    b.textContent = text;
    b.addEventListener('click', onclick);
    $('controls').appendChild(b);
    return b;
  }
  const ui = {};
  ui.mode = control('colour', selectEl(meta.modes.map((m) => [m.id, m.label]), state.mode, (v) => { state.mode = v; applyMode(); }));
  if (Y) ui.show = control('show', selectEl([['both', 'X and Y'], ['x', 'X'], ['y', 'Y']], state.show, (v) => { state.show = v; requestRender(); }));
  if (X.mesh || (Y && Y.mesh)) {
    ui.shading = control('shading', selectEl([['smooth', 'smooth'], ['flat', 'flat'], ['unlit', 'unlit']], state.shading, (v) => { state.shading = v; applyShading(); }));
    const wf = document.createElement('input');
    wf.type = 'checkbox';
    wf.addEventListener('change', () => { state.wireframe = wf.checked; applyShading(); });
    ui.wireframe = control('wireframe', wf);
  }
  button('reset view', () => { controls.reset(); requestRender(); });
  function snapshot() {
    render();
    return canvas.toDataURL('image/png');
  }
  button('save PNG', () => {
    render();
    canvas.toBlob((b) => {
      const a = document.createElement('a');
      a.href = URL.createObjectURL(b);
      a.download = (meta.title || 'funcorr').replace(/[^\w.-]+/g, '_') + '.png';
      a.click();
      setTimeout(() => URL.revokeObjectURL(a.href), 10000);
    }, 'image/png');
  });

  const caption = [];
  if (Y) caption.push(mapXY ? `map X → Y${mapYX ? ' (and Y → X)' : ''}` : 'no map');
  if (meta.method) caption.push(meta.method);
  if (meta.errors) {
    const e = meta.errors;
    caption.push(`mean geodesic error ×100 = ${(100 * e.mean).toFixed(2)} over ${e.points.toLocaleString('en')} template points ` +
      `(${(100 * e.at_005).toFixed(1)}% ≤ 0.05; symmetric flips ${e.symmetric ? '' : 'not '}allowed; ${e.geodesics})`);
  } else if (Y && mapXY) {
    caption.push('no ground truth given');
  }
  if (meta.map_yx_inferred) caption.push("Y's colours: from the nearest mapped vertex (no map Y → X given)");
  for (const n of meta.notes) caption.push(n);
  $('caption').textContent = caption.join(' · ');

  // ---- start --------------------------------------------------------------------------------
  applyShading();
  applyMode();
  requestAnimationFrame(() => {
    render();
    $('loading').remove();
    requestAnimationFrame(() => {
      hook.loadMs = performance.now();
      resolveReady(hook.loadMs);
    });
  });

  // ---- window.funcorr: the page's interface for tests and scripts ------------------------------
  const sideOf = (side) => (side === 'y' ? Y : X);
  Object.assign(hook, {
    /** Selects vertex i of X (or of Y with side 'y'); resolves to {x, y} once drawn. */
    pick(i, side = 'x') {
      const s = sideOf(side);
      if (!s || !(i >= 0 && i < s.n)) throw new RangeError(`no vertex ${i} on ${side}`);
      const r = select(side, i);
      return nextFrame().then(() => r);
    },
    /** Changes {mode, show, shading, wireframe}; resolves once drawn. */
    set(o) {
      if (o.mode !== undefined) {
        if (!modeById.has(o.mode)) throw new RangeError(`no colouring ${o.mode}`);
        state.mode = o.mode;
        ui.mode.value = o.mode;
        applyMode();
      }
      if (o.show !== undefined && Y) { state.show = o.show; ui.show.value = o.show; }
      if (o.shading !== undefined) { state.shading = o.shading; if (ui.shading) ui.shading.value = o.shading; }
      if (o.wireframe !== undefined) { state.wireframe = !!o.wireframe; if (ui.wireframe) ui.wireframe.checked = state.wireframe; }
      applyShading();
      return nextFrame();
    },
    /** Camera at azimuth, elevation (degrees); resolves once drawn. */
    view(az, el) { setView(az, el); return nextFrame(); },
    /** Where vertex i of side is drawn: {x, y} in CSS pixels of the page, and whether it is the
     * vertex seen there (not hidden behind the surface). */
    project(i, side = 'x') {
      const s = sideOf(side);
      const v = layout().find((l) => l.s === s);
      if (!v) return null;
      camera.aspect = v.w / v.h;
      camera.updateProjectionMatrix();
      const p = worldVertex(s, i).project(camera);
      const cx = v.x + (p.x + 1) / 2 * v.w, cy = v.y + (1 - p.y) / 2 * v.h;
      const hit = pickAt(cx, cy);
      const r = canvas.getBoundingClientRect();
      return { x: r.left + cx, y: r.top + cy, visible: !!hit && hit.vertex === i };
    },
    /** Shows the point preview of a large pair (as while dragging) or the full meshes. */
    preview(on) { setLod(!!on && BIG); return nextFrame().then(() => lod); },
    errorAt: (i) => (err ? err.values[i] : null),
    measuredAt: (i) => (err ? err.measured[i] === 1 : null),
    fieldAt: (id, i) => (fields.has(id) ? fields.get(id).data[i] : null),
    bar: (name) => meta.bars[name] || null,
    mapXY: (i) => (mapXY ? mapXY[i] : null),
    mapYX: (i) => (mapYX ? mapYX[i] : null),
    snapshot,
    state: () => ({ ...state }),
    /** Orbits the camera through k frames, each finished on the GPU (readPixels): ms per frame;
     * with preview true, as while the user drags (the point preview of large pairs). */
    timeFrames(k = 30, preview = false) {
      setLod(preview && BIG);
      const gl = renderer.getContext();
      const px = new Uint8Array(4);
      const ms = [];
      const start = camera.position.clone();
      for (let f = 0; f < k; f++) {
        camera.position.copy(start).applyAxisAngle(new THREE.Vector3(0, 1, 0), (2 * Math.PI * (f + 1)) / k);
        camera.lookAt(0, 0, 0);
        const t = performance.now();
        render();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
        ms.push(performance.now() - t);
      }
      controls.update();
      setLod(false);
      requestRender();
      const sorted = [...ms].sort((a, b) => a - b);
      return { frames: k, preview: preview && BIG, mean: ms.reduce((a, b) => a + b, 0) / k, median: sorted[k >> 1], max: sorted[k - 1], ms };
    },
  });
})();
