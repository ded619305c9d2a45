// The player of urdfpost's 3-D view: builds the machine from the view data and plays the
// program. Every pose comes from the data (Pinocchio's forward kinematics at samples of the
// joint path); between samples positions are interpolated linearly, rotations by slerp.
import * as THREE from '__THREE__';
import { OrbitControls } from '__ORBIT__';

function decode(text, Type) {
  const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
  return new Type(bytes.buffer);
}

function shapeMesh(shape) {
  let geometry;
  if (shape.kind === 'box') {
    geometry = new THREE.BoxGeometry(shape.size[0], shape.size[1], shape.size[2]);
  } else if (shape.kind === 'cylinder') {
    geometry = new THREE.CylinderGeometry(shape.radius, shape.radius, shape.length, 48);
    geometry.rotateX(Math.PI / 2); // three.js cylinders stand on Y, URDF ones on Z
  } else if (shape.kind === 'sphere') {
    geometry = new THREE.SphereGeometry(shape.radius, 32, 16);
  } else {
    geometry = meshGeometry(shape);
  }
  const [r, g, b, a] = shape.color;
  const material = new THREE.MeshStandardMaterial({
    color: new THREE.Color(r, g, b), transparent: a < 1, opacity: a, metalness: 0.2, roughness: 0.7,
  });
  const mesh = new THREE.Mesh(geometry, material);
  mesh.matrixAutoUpdate = false;
  mesh.matrix.fromArray(shape.origin);
  mesh.name = shape.name;
  return mesh;
}

function meshGeometry(shape) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(decode(shape.positions, Float32Array), 3));
  geometry.setIndex(new THREE.BufferAttribute(decode(shape.indices, Uint32Array), 1));
  geometry.computeVertexNormals();
  return geometry;
}

function place(object, pose, k) {
  object.position.set(pose[7 * k], pose[7 * k + 1], pose[7 * k + 2]);
  object.quaternion.set(pose[7 * k + 3], pose[7 * k + 4], pose[7 * k + 5], pose[7 * k + 6]);
}

function colorRamp(x) { // 0 -> blue, 0.5 -> green, 1 -> red
  const c = new THREE.Color();
  c.setHSL((1 - Math.min(Math.max(x, 0), 1)) * 0.66, 0.9, 0.5);
  return c;
}

export function start(data) {
  const t = decode(data.t, Float64Array);
  const poses = decode(data.poses, Float32Array);
  const tip = decode(data.tip, Float32Array);
  const axis = decode(data.axis, Float32Array);
  const q = decode(data.q, Float32Array);
  const move = decode(data.move, Int32Array);
  const line = decode(data.line, Int32Array);
  const n = data.samples;
  const nMoving = data.moving.length;
  const nAxes = data.axes.length;
  const end = t[n - 1];

  const host = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(host.clientWidth, host.clientHeight);
  host.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2026);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x303038, 1.0));
  const sun = new THREE.DirectionalLight(0xffffff, 1.2);
  sun.position.set(1, -2, 3);
  scene.add(sun);

  const groups = {};
  for (const link of Object.keys(data.bodies).concat(['workpiece'])) {
    if (groups[link]) continue;
    const group = new THREE.Group();
    group.name = link;
    for (const shape of data.bodies[link] || []) group.add(shapeMesh(shape));
    scene.add(group);
    groups[link] = group;
  }
  for (const [link, pose] of Object.entries(data.fixed)) place(groups[link], pose, 0);
  const work = groups.workpiece;

  const framed = [];
  if (data.stock) {
    const stock = new THREE.Mesh(meshGeometry(data.stock), new THREE.MeshStandardMaterial({
      color: 0xc8a070, transparent: true, opacity: 0.55, roughness: 0.8,
    }));
    work.add(stock);
    framed.push(stock);
  }
  if (data.cl) {
    const cl = new THREE.BufferGeometry();
    cl.setAttribute('position', new THREE.BufferAttribute(decode(data.cl, Float32Array), 3));
    const path = new THREE.Line(cl, new THREE.LineBasicMaterial({ color: 0x6fb7ff }));
    work.add(path);
    framed.push(path);
  }
  const trace = new THREE.BufferGeometry();
  trace.setAttribute('position', new THREE.BufferAttribute(tip, 3));
  const traceMaterial = new THREE.LineBasicMaterial({ color: 0xffe14d, vertexColors: !!data.color });
  if (data.color) {
    const values = decode(data.color.values, Float32Array);
    const colors = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) colorRamp(values[i] / data.color.max).toArray(colors, 3 * i);
    trace.setAttribute('color', new THREE.BufferAttribute(colors, 3));
  }
  const traceLine = new THREE.Line(trace, traceMaterial);
  traceLine.frustumCulled = false;
  work.add(traceLine);
  // a cylinder of diameter and length 1, from the tip up its axis, scaled to the tool loaded
  const toolSizes = data.tool.sizes ? decode(data.tool.sizes, Float32Array) : null;
  const toolGeometry = new THREE.CylinderGeometry(0.5, 0.5, 1, 32);
  toolGeometry.translate(0, 0.5, 0);
  const tool = new THREE.Mesh(toolGeometry, new THREE.MeshStandardMaterial({ color: 0xd0d4dc, metalness: 0.6, roughness: 0.3 }));
  tool.scale.set(data.tool.diameter, data.tool.length, data.tool.diameter);
  work.add(tool);
  const up = new THREE.Vector3(0, 1, 0);
  const tmpAxis = new THREE.Vector3();
  let cells = []; // the axis values' table cells (made with the panel below)
  let now = 0;
  let playing = false;
  let last = null;

  // frame the machine as it stands at the start
  const camera = new THREE.PerspectiveCamera(40, host.clientWidth / host.clientHeight, 1, 1e6);
  camera.up.set(0, 0, 1);
  const controls = new OrbitControls(camera, renderer.domElement);
  setTime(0);
  scene.updateMatrixWorld(true);
  // looking at the work (CL path, stock, tool), from far enough to see the whole machine
  const box = new THREE.Box3().setFromObject(scene);
  const size = box.getSize(new THREE.Vector3()).length() || 1000;
  const workBox = new THREE.Box3(); // the CL path and the stock (not the approach moves)
  for (const o of framed) workBox.expandByObject(o);
  const centre = (workBox.isEmpty() ? box : workBox).getCenter(new THREE.Vector3());
  const workSize = workBox.isEmpty() ? size : workBox.getSize(new THREE.Vector3()).length();
  const distance = Math.min(Math.max(workSize * 7, size * 0.15), size * 0.6);
  camera.position.copy(centre).add(new THREE.Vector3(0.5, -0.75, 0.42).multiplyScalar(distance));
  camera.near = size / 1000;
  camera.far = size * 20;
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();

  // the panel
  const slider = document.getElementById('slider');
  const play = document.getElementById('play');
  const speed = document.getElementById('speed');
  document.getElementById('title').textContent =
    `${data.title} · ${data.tcp ? 'TCP' : 'machine coordinates'} · ${data.units}` +
    (data.sampled_every > 1 ? ` · every ${data.sampled_every}th block shown` : '');
  const marks = document.getElementById('marks');
  for (const m of data.marks) {
    const div = document.createElement('div');
    div.className = m.kind;
    div.title = m.label;
    div.style.left = `${(100 * m.t0) / (end || 1)}%`;
    div.style.width = `${Math.max((100 * (m.t1 - m.t0)) / (end || 1), 0.2)}%`;
    marks.appendChild(div);
  }
  const legend = document.getElementById('legend');
  const kinds = { singular: 'singular span', rewind: 'rewind', worst: 'worst deviation' };
  for (const [kind, label] of Object.entries(kinds)) {
    if (!data.marks.some((m) => m.kind === kind)) continue;
    legend.insertAdjacentHTML('beforeend', `<span><i class="${kind}"></i>${label}</span>`);
  }
  legend.insertAdjacentHTML('beforeend', '<span><i style="background:#6fb7ff"></i>CL path</span>');
  if (data.color) {
    legend.insertAdjacentHTML('beforeend',
      `<span><i style="background:linear-gradient(90deg,#2040ff,#20ff40,#ff2020)"></i>trace by ${data.color.by}, 0..${data.color.max.toPrecision(3)} ${data.color.unit}</span>`);
  } else {
    legend.insertAdjacentHTML('beforeend', '<span><i style="background:#ffe14d"></i>tool tip trace</span>');
  }
  const axesTable = document.getElementById('axes');
  cells = data.axes.map((name) => {
    const row = axesTable.insertRow();
    row.insertCell().textContent = name;
    return row.insertCell();
  });

  function sampleAt(time) { // the last sample at or before time
    let lo = 0, hi = n - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (t[mid] <= time) lo = mid; else hi = mid - 1;
    }
    return lo;
  }

  function setTime(time) {
    now = Math.min(Math.max(time, 0), end);
    const i = sampleAt(now);
    const j = Math.min(i + 1, n - 1);
    const f = j > i && t[j] > t[i] ? (now - t[i]) / (t[j] - t[i]) : 0;
    const a = new THREE.Quaternion(), b = new THREE.Quaternion();
    for (let k = 0; k < nMoving; k++) {
      const o = groups[data.moving[k]];
      const pi = 7 * (i * nMoving + k), pj = 7 * (j * nMoving + k);
      o.position.set(
        poses[pi] + f * (poses[pj] - poses[pi]),
        poses[pi + 1] + f * (poses[pj + 1] - poses[pi + 1]),
        poses[pi + 2] + f * (poses[pj + 2] - poses[pi + 2]));
      a.set(poses[pi + 3], poses[pi + 4], poses[pi + 5], poses[pi + 6]);
      b.set(poses[pj + 3], poses[pj + 4], poses[pj + 5], poses[pj + 6]);
      o.quaternion.slerpQuaternions(a, b, f);
    }
    tool.position.set(
      tip[3 * i] + f * (tip[3 * j] - tip[3 * i]),
      tip[3 * i + 1] + f * (tip[3 * j + 1] - tip[3 * i + 1]),
      tip[3 * i + 2] + f * (tip[3 * j + 2] - tip[3 * i + 2]));
    tmpAxis.set(
      axis[3 * i] + f * (axis[3 * j] - axis[3 * i]),
      axis[3 * i + 1] + f * (axis[3 * j + 1] - axis[3 * i + 1]),
      axis[3 * i + 2] + f * (axis[3 * j + 2] - axis[3 * i + 2])).normalize();
    tool.quaternion.setFromUnitVectors(up, tmpAxis);
    if (toolSizes) tool.scale.set(toolSizes[2 * i], toolSizes[2 * i + 1], toolSizes[2 * i]);
    trace.setDrawRange(0, i + 1);
    const shown = f > 0 ? j : i;
    if (cells.length) {
      for (let c = 0; c < nAxes; c++) {
        const v = q[i * nAxes + c] + f * (q[j * nAxes + c] - q[i * nAxes + c]);
        cells[c].textContent = v.toFixed(data.rotary[c] ? 3 : (data.units === 'inch' ? 4 : 3));
      }
      document.getElementById('block').textContent =
        `block ${move[shown] + 1} of ${data.moves} · NC line ${line[shown]}`;
      document.getElementById('nc').textContent = data.text[String(line[shown])] || '';
      document.getElementById('time').textContent = `${now.toFixed(1)} / ${end.toFixed(1)} s`;
      const diameter = toolSizes ? toolSizes[2 * shown] : data.tool.diameter;
      document.getElementById('tool').textContent = `tool \u00d8${diameter.toFixed(3)} mm`;
      slider.value = end > 0 ? now / end : 0;
    }
  }

  function frame(stamp) {
    if (playing) {
      if (last !== null) setTime(now + ((stamp - last) / 1000) * Number(speed.value));
      last = stamp;
      if (now >= end) { playing = false; play.textContent = 'Play'; }
    }
    controls.update();
    renderer.render(scene, camera);
    requestAnimationFrame(frame);
  }

  play.addEventListener('click', () => {
    playing = !playing;
    last = null;
    if (playing && now >= end) setTime(0);
    play.textContent = playing ? 'Pause' : 'Play';
  });
  slider.addEventListener('input', () => { playing = false; play.textContent = 'Play'; setTime(slider.value * end); });
  window.addEventListener('resize', () => {
    camera.aspect = host.clientWidth / host.clientHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(host.clientWidth, host.clientHeight);
  });

  // #t=SECONDS (or #f=FRACTION) opens the view paused at that time; otherwise it plays
  const hash = new URLSearchParams(location.hash.slice(1));
  if (hash.has('t')) setTime(Number(hash.get('t')));
  else if (hash.has('f')) setTime(Number(hash.get('f')) * end);
  else { setTime(0); playing = true; play.textContent = 'Pause'; }
  renderer.render(scene, camera);
  const status = document.getElementById('status');
  if (status.dataset.state !== 'error') {
    status.dataset.state = 'ready';
    status.textContent = JSON.stringify({ samples: n, time: now, end, bodies: scene.children.length });
  }
  requestAnimationFrame(frame);
}
