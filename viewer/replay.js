// pegtwin replay viewer: plays back a recorded trial with WebGL. No libraries, no network.
// The data format is in README.md beside this file.
(function () {
  'use strict';

  // ---------- data ----------
  const data = JSON.parse(document.getElementById('replay-data').textContent);
  const bytesOf = (b64) => {
    const bin = atob(b64);
    const out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  };
  const f32 = (b64) => new Float32Array(bytesOf(b64).buffer);
  const u32 = (b64) => new Uint32Array(bytesOf(b64).buffer);
  const F = data.frames;
  const frames = {
    count: F.count,
    time: f32(F.time_s),
    phase: bytesOf(F.phase),
    contact: bytesOf(F.contact),
    links: f32(F.links),
    peg: f32(F.peg),
    est: f32(F.est_wrench),
    tru: f32(F.true_wrench),
  };
  const linkCount = data.links.length;

  // ---------- small linear algebra (column-major 4x4) ----------
  const M = {
    ident() { const m = new Float32Array(16); m[0] = m[5] = m[10] = m[15] = 1; return m; },
    mul(a, b) {
      const o = new Float32Array(16);
      for (let c = 0; c < 4; c++)
        for (let r = 0; r < 4; r++) {
          let s = 0;
          for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
          o[c * 4 + r] = s;
        }
      return o;
    },
    // pose [x y z qx qy qz qw] (at offset) to a matrix
    pose(p, o = 0) {
      const [x, y, z, qx, qy, qz, qw] = [p[o], p[o + 1], p[o + 2], p[o + 3], p[o + 4], p[o + 5], p[o + 6]];
      const m = new Float32Array(16);
      m[0] = 1 - 2 * (qy * qy + qz * qz); m[1] = 2 * (qx * qy + qz * qw); m[2] = 2 * (qx * qz - qy * qw);
      m[4] = 2 * (qx * qy - qz * qw); m[5] = 1 - 2 * (qx * qx + qz * qz); m[6] = 2 * (qy * qz + qx * qw);
      m[8] = 2 * (qx * qz + qy * qw); m[9] = 2 * (qy * qz - qx * qw); m[10] = 1 - 2 * (qx * qx + qy * qy);
      m[12] = x; m[13] = y; m[14] = z; m[15] = 1;
      return m;
    },
    perspective(fovy, aspect, near, far) {
      const f = 1 / Math.tan(fovy / 2), m = new Float32Array(16);
      m[0] = f / aspect; m[5] = f; m[10] = (far + near) / (near - far); m[11] = -1;
      m[14] = 2 * far * near / (near - far);
      return m;
    },
    lookAt(eye, at, up) {
      const z = norm(sub(eye, at)), x = norm(cross(up, z)), y = cross(z, x), m = new Float32Array(16);
      m[0] = x[0]; m[4] = x[1]; m[8] = x[2];
      m[1] = y[0]; m[5] = y[1]; m[9] = y[2];
      m[2] = z[0]; m[6] = z[1]; m[10] = z[2];
      m[12] = -dot(x, eye); m[13] = -dot(y, eye); m[14] = -dot(z, eye); m[15] = 1;
      return m;
    },
    // a frame at p whose z runs along unit d, scaled (r, r, len)
    arrow(p, d, r, len) {
      const helper = Math.abs(d[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0];
      const x = norm(cross(helper, d)), y = cross(d, x), m = new Float32Array(16);
      m[0] = x[0] * r; m[1] = x[1] * r; m[2] = x[2] * r;
      m[4] = y[0] * r; m[5] = y[1] * r; m[6] = y[2] * r;
      m[8] = d[0] * len; m[9] = d[1] * len; m[10] = d[2] * len;
      m[12] = p[0]; m[13] = p[1]; m[14] = p[2]; m[15] = 1;
      return m;
    },
  };
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const len3 = (a) => Math.sqrt(dot(a, a));
  const norm = (a) => { const l = len3(a) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };
  // the inverse of a rigid pose matrix applied to point p
  const intoFrame = (m, p) => {
    const d = sub(p, [m[12], m[13], m[14]]);
    return [d[0] * m[0] + d[1] * m[1] + d[2] * m[2], d[0] * m[4] + d[1] * m[5] + d[2] * m[6],
      d[0] * m[8] + d[1] * m[9] + d[2] * m[10]];
  };

  // ---------- WebGL ----------
  const canvas = document.getElementById('gl');
  const gl = canvas.getContext('webgl', { antialias: true, preserveDrawingBuffer: true });
  if (!gl) {
    document.getElementById('nogl').style.display = 'block';
  }
  const VS = `
    attribute vec3 aPos; attribute vec3 aNormal;
    uniform mat4 uModel; uniform mat4 uViewProj;
    varying vec3 vNormal; varying vec3 vWorld;
    void main() {
      vec4 w = uModel * vec4(aPos, 1.0);
      vWorld = w.xyz; vNormal = mat3(uModel) * aNormal;
      gl_Position = uViewProj * w;
    }`;
  const FS = `
    precision highp float;
    uniform vec4 uColour; uniform vec3 uEye; uniform vec4 uClip; uniform float uLit;
    varying vec3 vNormal; varying vec3 vWorld;
    void main() {
      if (dot(uClip.xyz, vWorld) + uClip.w > 0.0) discard;
      vec3 n = normalize(vNormal);
      vec3 v = normalize(uEye - vWorld);
      float facing = dot(n, v);
      float shade = facing >= 0.0 ? 0.35 + 0.65 * facing : 0.45 + 0.35 * -facing;
      vec3 c = mix(uColour.rgb, uColour.rgb * shade, uLit);
      gl_FragColor = vec4(c, uColour.a);
    }`;
  function compile(type, src) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  let prog, loc;
  if (gl) {
    prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    loc = {};
    for (const a of ['aPos', 'aNormal']) loc[a] = gl.getAttribLocation(prog, a);
    for (const u of ['uModel', 'uViewProj', 'uColour', 'uEye', 'uClip', 'uLit']) loc[u] = gl.getUniformLocation(prog, u);
  }

  // An indexed mesh expanded to flat-shaded triangles.
  function upload(positions, indices) {
    const n = indices.length, pos = new Float32Array(n * 3), nor = new Float32Array(n * 3);
    for (let t = 0; t < n; t += 3) {
      const v = [0, 1, 2].map((k) => { const i = indices[t + k] * 3; return [positions[i], positions[i + 1], positions[i + 2]]; });
      const fn = norm(cross(sub(v[1], v[0]), sub(v[2], v[0])));
      for (let k = 0; k < 3; k++) {
        pos.set(v[k], (t + k) * 3);
        nor.set(fn, (t + k) * 3);
      }
    }
    return buffers(pos, nor, gl.TRIANGLES);
  }
  function buffers(pos, nor, mode) {
    const p = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, p); gl.bufferData(gl.ARRAY_BUFFER, pos, gl.STATIC_DRAW);
    const q = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, q); gl.bufferData(gl.ARRAY_BUFFER, nor, gl.STATIC_DRAW);
    return { p, q, count: pos.length / 3, mode };
  }
  const meshOf = (m) => upload(f32(m.positions), u32(m.indices));

  // A unit arrow along +z: a shaft of radius 1 to z = 0.8 and a head of radius 2.5.
  function arrowMesh() {
    const pos = [], idx = [], seg = 16;
    const ring = (r, z) => { const s = pos.length / 3; for (let i = 0; i < seg; i++) { const a = 2 * Math.PI * i / seg; pos.push(r * Math.cos(a), r * Math.sin(a), z); } return s; };
    const a = ring(1, 0), b = ring(1, 0.8), c = ring(2.5, 0.8);
    const tip = pos.length / 3; pos.push(0, 0, 1);
    const base = pos.length / 3; pos.push(0, 0, 0);
    for (let i = 0; i < seg; i++) {
      const j = (i + 1) % seg;
      idx.push(a + i, a + j, b + j, a + i, b + j, b + i);
      idx.push(c + i, c + j, tip);
      idx.push(base, a + j, a + i);
      idx.push(b + i, b + j, c + j, b + i, c + j, c + i);
    }
    return upload(new Float32Array(pos), new Uint32Array(idx));
  }
  // The floor: a 2 m grid at z = 0, 0.1 m apart.
  function gridLines() {
    const pos = [];
    for (let i = -10; i <= 10; i++) {
      const s = i * 0.1;
      pos.push(-1, s, 0, 1, s, 0, s, -1, 0, s, 1, 0);
    }
    const p = new Float32Array(pos), n = new Float32Array(p.length);
    for (let i = 2; i < n.length; i += 3) n[i] = 1;
    return buffers(p, n, gl.LINES);
  }

  const COLOURS = {
    arm: [0.80, 0.82, 0.85, 1], armDark: [0.55, 0.58, 0.62, 1], peg: [0.93, 0.47, 0.13, 1],
    hole: [0.45, 0.56, 0.68, 1], ghost: [0.15, 0.70, 0.35, 0.2], trueF: [0.85, 0.12, 0.12, 1],
    estF: [0.15, 0.35, 0.95, 1], grid: [0.70, 0.72, 0.76, 1],
  };
  const meshes = gl ? {
    links: data.links.map((l) => meshOf(l.mesh)),
    peg: meshOf(data.peg),
    hole: meshOf(data.hole),
    arrow: arrowMesh(),
    grid: gridLines(),
  } : null;
  const trueHole = data.true_hole ? M.pose(data.true_hole) : null;
  const estHole = data.estimated_hole ? M.pose(data.estimated_hole) : null;

  // ---------- camera ----------
  const focus = trueHole ? [trueHole[12], trueHole[13], trueHole[14]] : [0.5, 0, 0.1];
  const VIEWS = {
    close: { target: add(focus, [0, 0, -0.008]), dist: 0.2, yaw: -0.9, pitch: 0.14 },
    arm: { target: [focus[0] * 0.5, focus[1] * 0.5, 0.45], dist: 1.7, yaw: -0.9, pitch: 0.3 },
  };
  const cam = { target: focus.slice(), dist: 0.16, yaw: -0.9, pitch: 0.35 };
  const setView = (name) => { const v = VIEWS[name] || VIEWS.close; Object.assign(cam, v, { target: v.target.slice() }); };
  const eyeOf = () => add(cam.target, scale([Math.cos(cam.pitch) * Math.cos(cam.yaw), Math.cos(cam.pitch) * Math.sin(cam.yaw), Math.sin(cam.pitch)], cam.dist));

  // ---------- state and UI ----------
  const ui = (id) => document.getElementById(id);
  const state = { frame: 0, playing: false, time: 0, last: null, dirty: true };
  const scrub = ui('scrub');
  scrub.max = String(Math.max(frames.count - 1, 0));
  const frameAt = (t) => {
    let lo = 0, hi = frames.count - 1;
    if (hi < 0) return 0;
    while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (frames.time[mid] <= t + 1e-6) lo = mid; else hi = mid - 1; }
    return lo;
  };
  const lastTime = () => (frames.count ? frames.time[frames.count - 1] : 0);
  function setFrame(i) {
    state.frame = Math.max(0, Math.min(frames.count - 1, i | 0));
    state.time = frames.count ? frames.time[state.frame] : 0;
    scrub.value = String(state.frame);
    state.dirty = true;
  }
  function setPlaying(p) {
    state.playing = p && frames.count > 1;
    if (state.playing && state.frame >= frames.count - 1) setFrame(0);
    ui('play').innerHTML = state.playing ? '&#10074;&#10074;' : '&#9654;';
    state.last = null;
    if (state.playing) requestAnimationFrame(tick);
  }

  const PHASE_COLOURS = { sample: '#999', search: '#8e6cc0', observe: '#2f8fd0', retract: '#e0a020', align: '#40b0a0', insert: '#d05030' };
  function drawPhaseStrip() {
    const c = ui('phases'), w = c.clientWidth || 600;
    c.width = w;
    const g = c.getContext('2d'), T = Math.max(lastTime(), 1e-9);
    g.clearRect(0, 0, w, c.height);
    for (let i = 0; i < frames.count; i++) {
      const t0 = frames.time[i], t1 = i + 1 < frames.count ? frames.time[i + 1] : t0 + data.frame_dt_s;
      g.fillStyle = PHASE_COLOURS[data.phases[frames.phase[i]]] || '#888';
      g.fillRect(Math.floor(t0 / T * w), 0, Math.ceil((t1 - t0) / T * w) + 1, c.height);
    }
    g.fillStyle = '#fff';
    g.font = '10px sans-serif';
    let prev = -1;
    for (let i = 0; i < frames.count; i++) {
      if (frames.phase[i] !== prev) { prev = frames.phase[i]; g.fillText(data.phases[prev], frames.time[i] / T * w + 3, 10); }
    }
  }

  function fillInfo() {
    const r = data.trial, rows = [];
    ui('heading').textContent = `${data.geometry} at ${r.clearance_mm} mm`;
    rows.push(['method', r.method], ['seed', r.seed], ['outcome', r.outcome], ['t_obs', `${r.t_obs_s} s`]);
    rows.push(['hole offset', r.offset.slice(0, 3).map((v) => v.toFixed(2)).join(', ') + ' mm; ' + r.offset.slice(3).map((v) => v.toFixed(2)).join(', ') + ' deg']);
    if (r.errors) {
      const e = r.errors;
      rows.push(['estimate error', `${e.x_mm.toFixed(2)}, ${e.y_mm.toFixed(2)}, ${e.z_mm.toFixed(2)} mm; ${e.roll_deg.toFixed(2)}, ${e.pitch_deg.toFixed(2)}, ${e.yaw_deg.toFixed(2)} deg`]);
    }
    if (r.final_depth_mm !== null && r.final_depth_mm !== undefined) rows.push(['final depth', `${r.final_depth_mm.toFixed(2)} mm`]);
    rows.push(['peak |Fz| inserting', `${r.peak_fz_n.toFixed(1)} N`]);
    if (r.fault) rows.push(['sim_fault', `${r.fault.time_s.toFixed(3)} s: ${r.fault.reason}`]);
    if (r.stopped) rows.push(['stopped', r.stopped]);
    ui('info').innerHTML = '';
    for (const [k, v] of rows) {
      const tr = ui('info').insertRow();
      tr.insertCell().textContent = k;
      tr.insertCell().textContent = String(v);
    }
    ui('record').textContent = JSON.stringify(r, null, 1);
    const legend = [['peg', COLOURS.peg], ['arm', COLOURS.arm], ['true hole', COLOURS.hole], ['estimated hole', COLOURS.ghost],
      ['true contact force', COLOURS.trueF], ['estimated force (joint torques)', COLOURS.estF]];
    ui('legend').innerHTML = legend.map(([n, c]) => `<div><span style="background:rgb(${c.slice(0, 3).map((v) => Math.round(v * 255)).join(',')})"></span>${n}</div>`).join('');
  }

  function fillNow() {
    const i = state.frame, rows = [];
    if (!frames.count) { ui('now').innerHTML = '<tr><td>no frames recorded</td></tr>'; return; }
    rows.push(['phase', data.phases[frames.phase[i]]], ['contact', frames.contact[i] ? 'yes' : 'no']);
    const f = (a) => [a[i * 6], a[i * 6 + 1], a[i * 6 + 2]];
    rows.push(['|F| true', `${len3(f(frames.tru)).toFixed(2)} N (Fz ${frames.tru[i * 6 + 2].toFixed(2)})`]);
    rows.push(['|F| estimated', `${len3(f(frames.est)).toFixed(2)} N (Fz ${frames.est[i * 6 + 2].toFixed(2)})`]);
    if (trueHole) {
      const peg = M.pose(frames.peg, i * 7), tip = intoFrame(trueHole, [peg[12], peg[13], peg[14]]);
      rows.push(['tip in hole', `${(tip[0] * 1e3).toFixed(2)}, ${(tip[1] * 1e3).toFixed(2)}, ${(tip[2] * 1e3).toFixed(2)} mm`]);
    }
    ui('now').innerHTML = '';
    for (const [k, v] of rows) { const tr = ui('now').insertRow(); tr.insertCell().textContent = k; tr.insertCell().textContent = v; }
    ui('time').textContent = `t = ${state.time.toFixed(3)} s / ${lastTime().toFixed(2)} s`;
  }

  // ---------- drawing ----------
  function draw() {
    state.dirty = false;
    fillNow();
    if (!gl) return;
    const w = canvas.clientWidth, h = canvas.clientHeight, dpr = window.devicePixelRatio || 1;
    if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
      canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
    }
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.91, 0.925, 0.94, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.disable(gl.CULL_FACE);
    gl.useProgram(prog);
    const eye = eyeOf();
    const proj = M.perspective(0.8, canvas.width / Math.max(canvas.height, 1), cam.dist * 0.01, cam.dist * 50);
    gl.uniformMatrix4fv(loc.uViewProj, false, M.mul(proj, M.lookAt(eye, cam.target, [0, 0, 1])));
    gl.uniform3fv(loc.uEye, eye);
    const noClip = [0, 0, 0, -1];
    const i = state.frame;
    const body = (mesh, model, colour, clip = noClip, lit = 1) => {
      gl.uniformMatrix4fv(loc.uModel, false, model);
      gl.uniform4fv(loc.uColour, colour);
      gl.uniform4fv(loc.uClip, clip);
      gl.uniform1f(loc.uLit, lit);
      gl.bindBuffer(gl.ARRAY_BUFFER, mesh.p);
      gl.enableVertexAttribArray(loc.aPos);
      gl.vertexAttribPointer(loc.aPos, 3, gl.FLOAT, false, 0, 0);
      gl.bindBuffer(gl.ARRAY_BUFFER, mesh.q);
      gl.enableVertexAttribArray(loc.aNormal);
      gl.vertexAttribPointer(loc.aNormal, 3, gl.FLOAT, false, 0, 0);
      gl.drawArrays(mesh.mode, 0, mesh.count);
    };
    body(meshes.grid, M.ident(), COLOURS.grid, noClip, 0);
    if (frames.count) {
      for (let k = 0; k < linkCount; k++) {
        body(meshes.links[k], M.pose(frames.links, (i * linkCount + k) * 7), k % 2 ? COLOURS.arm : COLOURS.armDark);
      }
      const peg = M.pose(frames.peg, i * 7);
      body(meshes.peg, peg, COLOURS.peg);
    }
    // The hole, cut open by the plane through its axis that faces the camera.
    const section = ui('section').checked;
    const clipOf = (hole) => {
      if (!section) return noClip;
      const o = [hole[12], hole[13], hole[14]], axis = [hole[8], hole[9], hole[10]];
      const v = sub(eye, o), n = norm(sub(v, scale(axis, dot(v, axis))));
      return [n[0], n[1], n[2], -dot(n, o)];
    };
    if (trueHole) body(meshes.hole, trueHole, COLOURS.hole, clipOf(trueHole));
    if (estHole && ui('ghost').checked) {
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      body(meshes.hole, estHole, COLOURS.ghost, clipOf(estHole));
      gl.depthMask(true);
      gl.disable(gl.BLEND);
    }
    drawWrenches(body);
  }

  // The true and the estimated contact force as arrows from the peg tip, drawn over everything
  // (the tip is usually inside the hole).
  function drawWrenches(body) {
    if (!frames.count) return;
    const i = state.frame, peg = M.pose(frames.peg, i * 7);
    const at = [peg[12], peg[13], peg[14]], per = Number(ui('arrow').value);
    gl.disable(gl.DEPTH_TEST);
    // the true force wider, so that the estimate drawn inside it leaves its edge in sight
    for (const [w, colour, r] of [[frames.tru, COLOURS.trueF, 0.003], [frames.est, COLOURS.estF, 0.0015]]) {
      const f = [w[i * 6], w[i * 6 + 1], w[i * 6 + 2]], n = len3(f);
      if (n * per > 1e-4) body(meshes.arrow, M.arrow(at, scale(f, 1 / n), cam.dist * r, n * per), colour);
    }
    gl.enable(gl.DEPTH_TEST);
  }

  function tick(now) {
    if (state.playing) {
      if (state.last !== null) {
        const t = state.time + (now - state.last) / 1000 * Number(ui('speed').value);
        if (t >= lastTime()) { setFrame(frames.count - 1); setPlaying(false); } else { state.frame = frameAt(t); scrub.value = String(state.frame); state.time = t; state.dirty = true; }
      }
      state.last = now;
    }
    if (state.dirty) draw();
    if (state.playing) requestAnimationFrame(tick);
  }
  const redraw = () => { if (!state.dirty) { state.dirty = true; requestAnimationFrame(tick); } };

  // ---------- input ----------
  scrub.addEventListener('input', () => { setFrame(Number(scrub.value)); setPlaying(false); redraw(); draw(); });
  ui('play').addEventListener('click', () => setPlaying(!state.playing));
  ui('camera').addEventListener('change', () => { setView(ui('camera').value); redraw(); });
  for (const id of ['section', 'ghost', 'arrow']) ui(id).addEventListener('change', redraw);
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey }; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener('pointerup', () => { drag = null; });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) {
      const eye = eyeOf(), fwd = norm(sub(cam.target, eye)), right = norm(cross(fwd, [0, 0, 1])), up = cross(right, fwd);
      const k = cam.dist * 0.0015;
      cam.target = add(cam.target, add(scale(right, -dx * k), scale(up, dy * k)));
    } else {
      cam.yaw -= dx * 0.008;
      cam.pitch = Math.max(-1.5, Math.min(1.5, cam.pitch + dy * 0.008));
    }
    redraw();
  });
  canvas.addEventListener('wheel', (e) => { e.preventDefault(); cam.dist *= Math.exp(e.deltaY * 0.001); redraw(); }, { passive: false });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' && e.target.type !== 'checkbox') return;
    if (e.code === 'Space') { e.preventDefault(); setPlaying(!state.playing); } else if (e.code === 'ArrowRight') { setFrame(state.frame + 1); redraw(); } else if (e.code === 'ArrowLeft') { setFrame(state.frame - 1); redraw(); }
  });
  window.addEventListener('resize', () => { drawPhaseStrip(); redraw(); });

  // ---------- start: #t=SECONDS&camera=arm|close ----------
  const params = new URLSearchParams(location.hash.slice(1));
  setView(params.get('camera') || 'close');
  ui('camera').value = VIEWS[params.get('camera')] ? params.get('camera') : 'close';
  fillInfo();
  drawPhaseStrip();
  const t = params.has('t') ? Number(params.get('t')) : NaN;
  setFrame(Number.isFinite(t) ? frameAt(t) : 0);
  draw();
  document.documentElement.dataset.drawnMs = String(Math.round(performance.now()));
  if (!params.has('t')) setPlaying(true);
})();
