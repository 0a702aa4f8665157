// The trainer viewer's page: the scene the viewer serves (/scene.json, /model/<i>.bin) drawn
// with three.js, one binary WebSocket frame per telemetry frame (layout: tools/viewer/src/
// view_frame.hpp, docs/viewer.md). Measurements for tests and tools are in window.viewerStats.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { decodeFrame } from './frame.js';
import { ModalRebuilder } from './reconstruct.js';

const stats = {
  connected: false, sceneLoaded: false, framesReceived: 0, framesDrawn: 0, rafCount: 0,
  lastCycle: 0, lastSequence: 0, faults: 0, frameBytes: 0, error: '',
  // Per drawn frame, ms: [cycle→sent, sent→viewer, viewer→ws, ws→page, page→drawn, cycle→drawn]
  hops: [], rebuildMs: [], drawnRate: 0, rafRate: 0,
  peakDisplacementM: [],  // per model: the largest |u| component drawn so far (tissue models)
};
window.viewerStats = stats;
const nowMs = () => performance.timeOrigin + performance.now();  // CLOCK_REALTIME-based, ms

const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(view.clientWidth, view.clientHeight);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2125);
const camera = new THREE.PerspectiveCamera(40, view.clientWidth / view.clientHeight, 0.001, 5);
camera.up.set(0, 0, 1);  // the trainer frame: z up, shafts go into the body along -z
const controls = new OrbitControls(camera, renderer.domElement);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(0.3, -0.5, 1.0);
scene.add(sun);
window.addEventListener('resize', () => {
  camera.aspect = view.clientWidth / view.clientHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(view.clientWidth, view.clientHeight);
});

const tissueColours = { modal_shell: 0xd98c8c, tet_tensor: 0x9c4a3c };
let sceneInfo = null;
const drawn = [];        // per model: { kind, mesh|tube, rest, rebuilder }
const instruments = [];  // per instrument: { shaft, jaws }
const arrows = [];       // contact force arrows, reused
let pending = null;      // the newest frame not drawn yet

function placementMatrix(m) {
  const r = m.rotation, t = m.translation_m;
  return new THREE.Matrix4().set(r[0], r[1], r[2], t[0], r[3], r[4], r[5], t[1],
                                 r[6], r[7], r[8], t[2], 0, 0, 0, 1);
}

function section(buffer, layout, name, Type) {
  const [word, count] = layout[name];
  return new Type(buffer, word * 4, count);
}

function segment(radius, colour) {
  const mesh = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, 1, 12),
                              new THREE.MeshStandardMaterial({ color: colour, metalness: 0.6, roughness: 0.35 }));
  scene.add(mesh);
  return mesh;
}

const yAxis = new THREE.Vector3(0, 1, 0);
function placeSegment(mesh, a, b) {
  const dir = new THREE.Vector3().subVectors(b, a);
  const length = dir.length();
  mesh.visible = length > 1e-6;
  if (!mesh.visible) return;
  mesh.position.copy(a).addScaledVector(dir, 0.5);
  mesh.quaternion.setFromUnitVectors(yAxis, dir.divideScalar(length));
  mesh.scale.set(1, length, 1);
}

async function loadScene() {
  sceneInfo = await (await fetch('scene.json')).json();
  document.getElementById('title').textContent = `scene ${sceneInfo.scene}`;
  const box = new THREE.Box3();
  for (const m of sceneInfo.models) {
    const buffer = await (await fetch(m.data.replace(/^\//, ''))).arrayBuffer();
    const rest = section(buffer, m.layout, 'rest_positions', Float32Array);
    if (m.kind === 'catheter') {
      const entry = { kind: m.kind, rest, mesh: null,
                      material: new THREE.MeshStandardMaterial({ color: 0xe8d27a, roughness: 0.5 }) };
      drawn.push(entry);
      setCatheter(entry, rest);
      continue;
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(rest), 3));
    geometry.setIndex(new THREE.BufferAttribute(section(buffer, m.layout, 'triangles', Uint32Array), 1));
    geometry.computeVertexNormals();
    const mesh = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({
      color: tissueColours[m.kind], roughness: 0.7, side: THREE.DoubleSide }));
    mesh.matrixAutoUpdate = false;
    mesh.matrix.copy(placementMatrix(m));
    scene.add(mesh);
    mesh.updateMatrixWorld(true);
    geometry.computeBoundingBox();
    box.union(geometry.boundingBox.clone().applyMatrix4(mesh.matrixWorld));
    const rebuilder = m.browser_rebuilds ? new ModalRebuilder(m, buffer) : null;
    drawn.push({ kind: m.kind, rest, mesh, rebuilder });
  }
  for (const instrument of sceneInfo.instruments) {
    instruments.push({ shaft: segment(0.0025, 0x8a939c), jaws: [segment(0.0012, 0xc0c8d0), segment(0.0012, 0xc0c8d0)],
                       name: instrument.name });
  }
  if (box.isEmpty()) box.setFromCenterAndSize(new THREE.Vector3(0, 0, -0.1), new THREE.Vector3(0.1, 0.1, 0.1));
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
  controls.target.copy(centre);
  // The tissue models fill the middle of the view; the catheter's far end and the shafts may leave it.
  camera.position.copy(centre).add(new THREE.Vector3(0.6 * size, -3.0 * size, 1.6 * size));
  controls.update();
  stats.sceneLoaded = true;
}

// Where each tissue model lies on screen (CSS pixels), for tests that compare screenshots there.
function screenRects() {
  const rects = [];
  const canvas = renderer.domElement.getBoundingClientRect();
  for (const entry of drawn) {
    if (entry.kind === 'catheter' || !entry.mesh) { rects.push(null); continue; }
    entry.mesh.geometry.computeBoundingBox();
    const b = entry.mesh.geometry.boundingBox;
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    for (let c = 0; c < 8; ++c) {
      const p = new THREE.Vector3(c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y, c & 4 ? b.max.z : b.min.z)
        .applyMatrix4(entry.mesh.matrixWorld).project(camera);
      const x = canvas.left + (p.x + 1) / 2 * canvas.width, y = canvas.top + (1 - p.y) / 2 * canvas.height;
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    }
    rects.push({ x: Math.max(0, x0), y: Math.max(0, y0), width: Math.min(canvas.width, x1) - Math.max(0, x0),
                 height: Math.min(canvas.height, y1) - Math.max(0, y0) });
  }
  return rects;
}
window.viewerScreenRects = screenRects;

function setCatheter(entry, positions) {
  const points = [];
  for (let i = 0; i + 2 < positions.length; i += 3) points.push(new THREE.Vector3(positions[i], positions[i + 1], positions[i + 2]));
  if (points.length < 2) return;
  const geometry = new THREE.TubeGeometry(new THREE.CatmullRomCurve3(points), 8 * points.length, 0.00125, 10, false);
  if (entry.mesh) { entry.mesh.geometry.dispose(); entry.mesh.geometry = geometry; }
  else { entry.mesh = new THREE.Mesh(geometry, entry.material); scene.add(entry.mesh); }
}

const forceScale = 0.01;  // m of arrow per N
function draw(frame) {
  for (let i = 0; i < drawn.length; ++i) {
    const entry = drawn[i], data = frame.models[i];
    if (entry.kind === 'catheter') { setCatheter(entry, data.floats); continue; }
    let displacement = data.floats;
    if (entry.rebuilder) {
      const t0 = performance.now();
      displacement = entry.rebuilder.rebuild(data.floats, data.loads);
      stats.rebuildMs.push(performance.now() - t0);
    }
    const position = entry.mesh.geometry.attributes.position;
    const out = position.array, rest = entry.rest;
    let peak = stats.peakDisplacementM[i] || 0;
    for (let k = 0; k < out.length; ++k) {
      out[k] = rest[k] + displacement[k];
      peak = Math.max(peak, Math.abs(displacement[k]));
    }
    stats.peakDisplacementM[i] = peak;
    position.needsUpdate = true;
    entry.mesh.geometry.computeVertexNormals();
  }
  const v = (f, at) => new THREE.Vector3(f[at], f[at + 1], f[at + 2]);
  for (let i = 0; i < instruments.length; ++i) {
    const f = frame.instruments[i], tool = instruments[i];
    const hinge = v(f, 3);
    placeSegment(tool.shaft, v(f, 0), hinge);
    placeSegment(tool.jaws[0], hinge, v(f, 6));
    placeSegment(tool.jaws[1], hinge, v(f, 9));
  }
  // Contact force arrows: the force on the tissue, drawn ending at the contact point.
  while (arrows.length < frame.contacts.length) {
    const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0.02, 0x36c26b, 0.003, 0.0015);
    scene.add(arrow);
    arrows.push(arrow);
  }
  arrows.forEach((arrow, k) => {
    const c = frame.contacts[k];
    const force = c ? v(c, 3) : null;
    const magnitude = force ? force.length() : 0;
    arrow.visible = magnitude > 1e-4;
    if (!arrow.visible) return;
    const direction = force.divideScalar(magnitude);
    const length = Math.max(0.004, magnitude * forceScale);
    arrow.position.copy(v(c, 0)).addScaledVector(direction, -length);
    arrow.setDirection(direction);
    arrow.setLength(length, Math.min(0.003, 0.4 * length), 0.0015);
  });
  const banner = document.getElementById('banner');
  if (frame.faults !== 0 || stats.error) {
    banner.style.display = 'block';
    banner.textContent = frame.faults !== 0
      ? `FAULT: latched faults 0x${frame.faults.toString(16).padStart(8, '0')} — motors off`
      : stats.error;
  } else {
    banner.style.display = 'none';
  }
}

// ---- session panel: the viewer's session JSON (stream, metrics) plus the page's own figures.
let session = {};
function row(name, value) { return `<tr><td>${name}</td><td>${value}</td></tr>`; }
function sectionRow(name) { return `<tr class="section"><td colspan="2">${name}</td></tr>`; }
function fmt(x, digits = 1) { return typeof x === 'number' && isFinite(x) ? x.toFixed(digits) : '–'; }
function updatePanel(latestCycleNs) {
  const hops = stats.hops.slice(-60);
  const mean = (k) => hops.length ? hops.reduce((s, h) => s + h[k], 0) / hops.length : NaN;
  const sessionS = sceneInfo ? stats.lastCycle * sceneInfo.period_s : NaN;
  let html = row('cycle', stats.lastCycle) +
    row('session time', isFinite(sessionS) ? `${Math.floor(sessionS / 60)}:${(sessionS % 60).toFixed(1).padStart(4, '0')}` : '–') +
    row('wall time (UTC)', latestCycleNs ? new Date(latestCycleNs / 1e6).toISOString().substring(11, 23) : '–') +
    row('frames drawn /s', fmt(stats.drawnRate)) + row('display /s', fmt(stats.rafRate)) +
    row('latency cycle→drawn ms', fmt(mean(5))) + row('frame bytes', stats.frameBytes);
  const metrics = session.metrics;
  if (metrics && typeof metrics === 'object' && Object.keys(metrics).length) {
    html += sectionRow('trainee metrics');
    const add = (prefix, object) => {
      for (const [key, value] of Object.entries(object)) {
        const name = `${prefix}${key.replace(/_/g, ' ')}`;
        if (value && typeof value === 'object' && !Array.isArray(value)) add(`${name} · `, value);
        else html += row(name, typeof value === 'number' && !Number.isInteger(value) ? fmt(value, 3) : String(value));
      }
    };
    add('', metrics);
  }
  const stream = session.stream;
  if (stream && typeof stream === 'object' && stream.source === 'udp') {
    html += sectionRow('stream') + row('datagram bytes', stream.datagram_bytes) +
      row('received', stream.datagrams) + row('lost', stream.lost) +
      row('dropped (dup/late/stale)', `${stream.duplicates}/${stream.late}/${stream.stale}`) +
      row('malformed / refused', `${stream.malformed} / ${stream.refused}`);
  } else if (stream && typeof stream === 'object') {
    html += sectionRow('stream') + row('source', stream.source);
  }
  document.getElementById('session').innerHTML = html;
}

// ---- playback bar (a recording source): play/pause, seek slider, time
let playback = null;
let seeking = false;
function sendPlayback(request) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({ type: 'playback', ...request }));
}
function showPlayback(state) {
  playback = state;
  window.viewerPlayback = state;
  const bar = document.getElementById('playback');
  bar.style.display = 'flex';
  const seek = document.getElementById('seek');
  seek.max = String(state.duration_s);
  if (!seeking) seek.value = String(state.position_s);
  document.getElementById('play-pause').textContent = state.paused || state.ended ? 'play' : 'pause';
  document.getElementById('playback-time').textContent =
    `${state.position_s.toFixed(1)} / ${state.duration_s.toFixed(1)} s` + (state.speed !== 1 ? ` ×${state.speed}` : '') +
    (state.damage ? ' (file damaged: read up to it)' : '');
  if (state.damage) document.getElementById('playback').title = state.damage;
}
document.getElementById('play-pause').addEventListener('click', () => {
  sendPlayback({ action: playback && (playback.paused || playback.ended) ? 'play' : 'pause' });
});
const seekInput = document.getElementById('seek');
seekInput.addEventListener('input', () => { seeking = true; sendPlayback({ action: 'seek', t: Number(seekInput.value) }); });
seekInput.addEventListener('change', () => { seeking = false; sendPlayback({ action: 'seek', t: Number(seekInput.value) }); });
window.viewerPlaybackRequest = sendPlayback;

// ---- connection
let socket = null;
let latestCycleNs = 0;
function connect() {
  const url = new URL('ws', window.location.href);
  url.protocol = url.protocol === 'https:' ? 'wss:' : 'ws:';
  socket = new WebSocket(url);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => { stats.connected = true; document.getElementById('connection').textContent = `connected to ${url.host}`; };
  socket.onclose = () => {
    stats.connected = false;
    document.getElementById('connection').textContent = 'disconnected: retrying';
    setTimeout(connect, 1000);
  };
  socket.onmessage = (event) => {
    if (typeof event.data === 'string') {
      const message = JSON.parse(event.data);
      if (message.type === 'session') session = message;
      if (message.type === 'status') stats.error = message.error || '';
      if (message.type === 'playback') showPlayback(message);
      return;
    }
    const frame = decodeFrame(event.data, sceneInfo);
    frame.pageReceivedMs = nowMs();
    stats.framesReceived += 1;
    stats.frameBytes = event.data.byteLength;
    pending = frame;
    window.viewerLastFrame = frame;
  };
}

// ---- the display loop: the newest frame per display refresh; a frame's pixels are counted as
// on screen at the next refresh after it was rendered (the compositor shows it then).
let awaitingPresent = null;
let rateWindowStart = performance.now(), rateFrames = 0, rateRafs = 0;
function animate() {
  requestAnimationFrame(animate);
  const now = nowMs();
  stats.rafCount += 1;
  rateRafs += 1;
  if (awaitingPresent) {
    const f = awaitingPresent;
    awaitingPresent = null;
    if (f.times.cycleNs > 0 && f.times.sentNs > 0 && f.times.receivedNs > 0) {
      const cycleMs = f.times.cycleNs / 1e6;
      stats.hops.push([f.times.sentNs / 1e6 - cycleMs, (f.times.receivedNs - f.times.sentNs) / 1e6,
                       (f.times.handedNs - f.times.receivedNs) / 1e6, f.pageReceivedMs - f.times.handedNs / 1e6,
                       now - f.pageReceivedMs, now - cycleMs]);
      if (stats.hops.length > 200000) stats.hops.splice(0, 100000);
    }
  }
  if (pending && sceneInfo) {
    const frame = pending;
    pending = null;
    draw(frame);
    stats.framesDrawn += 1;
    rateFrames += 1;
    stats.lastCycle = frame.cycle;
    stats.lastSequence = frame.sequence;
    stats.faults = frame.faults;
    latestCycleNs = frame.times.cycleNs;
    awaitingPresent = frame;
  }
  controls.update();
  renderer.render(scene, camera);
  const elapsed = performance.now() - rateWindowStart;
  if (elapsed >= 1000) {
    stats.drawnRate = (1000 * rateFrames) / elapsed;
    stats.rafRate = (1000 * rateRafs) / elapsed;
    rateFrames = 0; rateRafs = 0; rateWindowStart = performance.now();
    updatePanel(latestCycleNs);
    if (socket && socket.readyState === WebSocket.OPEN) {
      socket.send(JSON.stringify({ type: 'page_stats', frames_drawn: stats.framesDrawn, drawn_per_s: stats.drawnRate,
                                   display_per_s: stats.rafRate, frames_received: stats.framesReceived }));
    }
  }
}

loadScene().then(() => { connect(); animate(); }).catch((error) => {
  stats.error = `viewer page: ${error}`;
  document.getElementById('banner').style.display = 'block';
  document.getElementById('banner').textContent = stats.error;
});
