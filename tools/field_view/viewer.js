// theia's guiding-field viewer: the field's leaves as boxes over a wireframe
// of the scene, seen from the render camera; a leaf's learned directional
// distribution beside the histogram of the directions it recorded.  Reads
// window.THEIA_FIELD (field.js, written by `theia field view`); three.js r111
// (Debian's libjs-three) draws.  window.theiaViewer is what tests drive.
'use strict';

const viewer = { errors: [], drawnLeaves: 0, leafCount: 0, selected: -1, ready: false };
window.theiaViewer = viewer;
function report(message) {
  viewer.errors.push(String(message));
  document.getElementById('errors').textContent = viewer.errors.join('\n');
}
window.addEventListener('error', (e) => report(e.message + ' (' + e.filename + ':' + e.lineno + ')'));

// --- data ---------------------------------------------------------------------

function bytes(base64) {
  const s = atob(base64), b = new Uint8Array(s.length);
  for (let i = 0; i < s.length; ++i) b[i] = s.charCodeAt(i);
  return b.buffer;
}

// A leaf's quadtree: 32-byte nodes of 4 float flux and 4 uint32 children (SamplingQuadNode).
function quadtree(base64) {
  const buffer = bytes(base64);
  return { flux: new Float32Array(buffer), child: new Uint32Array(buffer), nodes: buffer.byteLength / 32 };
}

// guiding/field_file.cpp's field_density: the density per unit area of the square at (cx, cy).
function density(q, cx, cy) {
  if (q.nodes === 0) return 0;
  let d = 1, n = 0;
  for (;;) {
    const f = q.flux, o = 8 * n;
    const total = (f[o] + f[o + 2]) + (f[o + 1] + f[o + 3]);
    if (!(total > 0)) return n === 0 ? 0 : d;
    const i = (cx >= 0.5 ? 1 : 0) | (cy >= 0.5 ? 2 : 0);
    cx = Math.fround(2 * cx), cy = Math.fround(2 * cy);
    cx -= Math.floor(cx), cy -= Math.floor(cy);
    d *= 4 * f[o + i] / total;
    const c = q.child[o + 4 + i];
    if (c === 0 || d === 0) return d;
    n = c;
  }
}

// A mixture leaf's lobes (--guiding-field vmm): 24-byte VMMLobe records of mu x y z, kappa, weight,
// inverse source distance, seen from leaf.pivot.  guiding/vmm.cpp's vmm_at and vmm_pdf follow, their
// float arithmetic rounded as C++ rounds it (Math.fround), so the map is `theia field image`'s.
const f32 = Math.fround;
const kMinKappa = f32(1e-3);
function vmfNorm(kappa) {
  if (kappa < kMinKappa) return f32(f32(1 / (4 * Math.PI)));
  return f32(Math.exp(Math.log(kappa) - Math.log(2 * Math.PI) - Math.log(-Math.expm1(-2 * kappa))));
}
// Each lobe re-pointed from the pivot towards its source, seen from p.
function mixtureAt(leaf, p) {
  const l = new Float32Array(bytes(leaf.lobes)), out = [];
  for (let k = 0; k + 5 < l.length; k += 6) {
    let mu = [l[k], l[k + 1], l[k + 2]];
    const inv = l[k + 5];
    if (inv > 0) {
      const v = [0, 1, 2].map((a) => f32(mu[a] + f32(inv * f32(leaf.pivot[a] - p[a]))));
      const len = f32(Math.sqrt(f32(f32(f32(v[0] * v[0]) + f32(v[1] * v[1])) + f32(v[2] * v[2]))));
      if (len > 1e-6 && isFinite(len)) mu = v.map((x) => f32(x / len));
    }
    out.push({ mu, kappa: l[k + 3] < kMinKappa ? 0 : l[k + 3], weight: l[k + 4], norm: vmfNorm(l[k + 3]) });
  }
  return out;
}
// The density per unit area of the square (pdf x 4 pi) at (cx, cy): guiding/field_file.cpp's field_leaf_density.
function mixtureDensity(m, cx, cy) {
  const cosTheta = f32(f32(2 * cx) - 1), sinTheta = f32(Math.sqrt(Math.max(0, f32(1 - f32(cosTheta * cosTheta)))));
  const phi = f32(f32(2 * f32(Math.PI)) * cy);
  const w = [f32(sinTheta * f32(Math.cos(phi))), f32(sinTheta * f32(Math.sin(phi))), cosTheta];
  let p = 0;
  for (const l of m) {
    if (!(l.weight > 0)) continue;
    const dot = f32(f32(f32(l.mu[0] * w[0]) + f32(l.mu[1] * w[1])) + f32(l.mu[2] * w[2]));
    p = f32(p + f32(f32(l.weight * l.norm) * f32(Math.exp(f32(l.kappa * f32(Math.min(dot, 1) - 1))))));
  }
  return p * 4 * Math.PI;
}

// Inferno at t = 0, 1/8, ..., 1: app/field_page.cpp has the same table and rounding.
const kColours = [[0, 0, 4], [31, 12, 72], [85, 15, 109], [136, 34, 106], [186, 54, 85], [227, 89, 51],
                  [249, 140, 10], [249, 201, 50], [252, 255, 164]];
function colour(t) {
  t = Math.min(Math.max(t, 0), 1) * 8;
  const i = Math.min(Math.floor(t), 7), f = t - i;
  return [0, 1, 2].map((k) => Math.floor(kColours[i][k] + f * (kColours[i + 1][k] - kColours[i][k]) + 0.5));
}
const logScale = (v, peak) => (v > 0 ? 1 + Math.log10(v / peak) / 3 : 0);

// Values per pixel of a width x height map, drawn on a log scale below their peak.
function drawMap(canvas, values) {
  const ctx = canvas.getContext('2d'), img = ctx.createImageData(canvas.width, canvas.height);
  let peak = 0;
  for (const v of values) peak = Math.max(peak, v);
  for (let i = 0; i < values.length; ++i) {
    const c = colour(logScale(values[i], peak));
    img.data[4 * i] = c[0], img.data[4 * i + 1] = c[1], img.data[4 * i + 2] = c[2], img.data[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
}

// The learned map, pixel for pixel as `theia field image` writes it at the leaf's centre
// (where the sphere shows it: a mixture's lobes are re-pointed to that point).
function learnedMap(leaf, width, height) {
  const values = new Float64Array(width * height);
  const b = leaf.box, centre = [0, 1, 2].map((a) => f32((b[a] + b[a + 3]) / 2));
  const m = leaf.lobes ? mixtureAt(leaf, centre) : [];
  const q = quadtree(leaf.quadtree);
  for (let y = 0; y < height; ++y)
    for (let x = 0; x < width; ++x) {
      const cx = Math.fround(1 - (y + 0.5) / height), cy = Math.fround((x + 0.5) / width);
      values[y * width + x] = m.length ? mixtureDensity(m, cx, cy) : density(q, cx, cy);
    }
  return values;
}

// The reservoir's directions binned on a coarser grid of the same map, spread back to pixels.
function histogramMap(leaf, width, height, weighted) {
  const s = new Float32Array(bytes(leaf.samples)), bx = 32, by = 16, bins = new Float64Array(bx * by);
  for (let k = 0; k + 3 < s.length; k += 4) {
    const cx = Math.min(Math.max(0.5 * (s[k + 2] + 1), 0), 0.999999);
    let phi = Math.atan2(s[k + 1], s[k]);
    if (phi < 0) phi += 2 * Math.PI;
    const cy = Math.min(phi / (2 * Math.PI), 0.999999);
    bins[Math.floor((1 - cx) * by) * bx + Math.floor(cy * bx)] += weighted ? s[k + 3] : 1;
  }
  const values = new Float64Array(width * height);
  for (let y = 0; y < height; ++y)
    for (let x = 0; x < width; ++x)
      values[y * width + x] = bins[Math.floor(y * by / height) * bx + Math.floor(x * bx / width)];
  return values;
}

// --- the 3D view --------------------------------------------------------------

const F = window.THEIA_FIELD;
const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x15171a);
// pbrt-v4's camera space is left-handed: mirror the world so a right-handed view shows the render's image.
const world = new THREE.Group();
if (F.camera.mirrored) world.scale.x = -1;
scene.add(world);
const toView = (v) => new THREE.Vector3(F.camera.mirrored ? -v[0] : v[0], v[1], v[2]);

const sb = F.scene_bounds, rb = F.root_bounds;
const sceneCentre = new THREE.Vector3((sb[0] + sb[3]) / 2, (sb[1] + sb[4]) / 2, (sb[2] + sb[5]) / 2);
const sceneSize = Math.hypot(sb[3] - sb[0], sb[4] - sb[1], sb[5] - sb[2]) || 1;
const camera = new THREE.PerspectiveCamera(F.camera.fov_y > 0 ? F.camera.fov_y : 45, 1, sceneSize * 1e-3, sceneSize * 20);
const controls = new THREE.OrbitControls(camera, renderer.domElement);

function renderCamera() {
  const eye = toView(F.camera.eye), forward = toView(F.camera.forward);
  const centre = toView([sceneCentre.x, sceneCentre.y, sceneCentre.z]);
  if (!(F.camera.fov_y > 0)) eye.copy(centre).addScaledVector(forward, -sceneSize);
  camera.up.copy(toView(F.camera.up));
  camera.position.copy(eye);
  const distance = Math.max(centre.clone().sub(eye).dot(forward), sceneSize * 0.05);
  controls.target.copy(eye).addScaledVector(forward, distance);
  camera.lookAt(controls.target);
  controls.update();
}

function resize() {
  // The render's aspect, as large as the panel allows.
  const aspect = F.camera.width / F.camera.height;
  let w = view.clientWidth, h = Math.round(w / aspect);
  if (h > view.clientHeight) h = view.clientHeight, w = Math.round(h * aspect);
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}

function addWireframe() {
  const triangles = new THREE.BufferGeometry();
  triangles.setAttribute('position', new THREE.BufferAttribute(new Float32Array(bytes(F.wireframe)), 3));
  const edges = new THREE.EdgesGeometry(triangles, 25);
  world.add(new THREE.LineSegments(edges, new THREE.LineBasicMaterial({ color: 0x6c7480 })));
}

// --- leaves ---------------------------------------------------------------------

const ui = (id) => document.getElementById(id);
let snapshot = null, leafMesh = null, leafEdges = null, shown = [], selection = null, sphere = null;

function column(name) { return snapshot.columns.indexOf(name); }
function value(leaf, c) { return snapshot.table[leaf * snapshot.columns.length + c]; }

// The box drawn for a leaf: the samples it recorded (clipped to it), or the leaf itself.
function drawnBox(i) {
  const b = snapshot.leaves[i].box, c = column('samples_min_x');
  if (!ui('seen').checked || c < 0) return b;
  const s = [0, 1, 2, 3, 4, 5].map((k) => value(i, c + k));
  // A flat box (one sample, or samples on a wall) gets a sliver of the leaf's size so it shows.
  for (let a = 0; a < 3; ++a) {
    const pad = 0.02 * (b[a + 3] - b[a]);
    if (s[a + 3] - s[a] < 2 * pad) s[a] = Math.max(b[a], s[a] - pad), s[a + 3] = Math.min(b[a + 3], s[a + 3] + pad);
  }
  return s;
}

function visible(i) {
  const b = snapshot.leaves[i].box;
  for (let a = 0; a < 3; ++a) {
    const plane = rb[a] + (ui('slice' + a).value / 1000) * (rb[a + 3] - rb[a]);
    if (b[a] > plane) return false;
  }
  return true;
}

// Leaf colours from the chosen column: its range over the leaves, linear or log.
function leafColours(c) {
  const v = snapshot.leaves.map((_, i) => value(i, c)), log = ui('logscale').checked;
  const t = log ? v.map((x) => (x > 0 ? Math.log10(x) : NaN)) : v;
  const finite = t.filter((x) => isFinite(x));
  const lo = Math.min(...finite), hi = Math.max(...finite);
  ui('range').textContent = snapshot.columns[c] + ': ' + Math.min(...v).toPrecision(4) + ' .. ' +
      Math.max(...v).toPrecision(4) + (log ? ' (log; zero is black)' : '');
  return t.map((x) => (isFinite(x) ? colour(hi > lo ? (x - lo) / (hi - lo) : 1) : [0, 0, 0]));
}

const kBoxCorners = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
const kBoxTriangles = [0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5];

const kBoxEdges = [0, 1, 1, 2, 2, 3, 3, 0, 4, 5, 5, 6, 6, 7, 7, 4, 0, 4, 1, 5, 2, 6, 3, 7];

// Per shown leaf, the box's corners by `indices` (triangles or edges) and its colour, as flat arrays.
function boxArrays(colours, indices) {
  const n = indices.length * 3, position = new Float32Array(shown.length * n), rgb = new Float32Array(shown.length * n);
  shown.forEach((leaf, k) => {
    const b = drawnBox(leaf), c = colours[leaf];
    indices.forEach((corner, j) => {
      const o = k * n + j * 3;
      for (let a = 0; a < 3; ++a) {
        position[o + a] = kBoxCorners[corner][a] ? b[a + 3] : b[a];
        rgb[o + a] = c[a] / 255;
      }
    });
  });
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(position, 3));
  g.setAttribute('color', new THREE.BufferAttribute(rgb, 3));
  return g;
}

// Faces faint (a camera inside the field would see nothing else) and edges in the leaf's colour.
function buildLeaves() {
  for (const old of [leafMesh, leafEdges]) if (old) world.remove(old), old.geometry.dispose();
  shown = snapshot.leaves.map((_, i) => i).filter(visible);
  const colours = leafColours(Number(ui('stat').value));
  leafMesh = new THREE.Mesh(boxArrays(colours, kBoxTriangles), new THREE.MeshBasicMaterial({
    vertexColors: THREE.VertexColors, transparent: true, opacity: 0.12, depthWrite: false, side: THREE.DoubleSide }));
  leafEdges = new THREE.LineSegments(boxArrays(colours, kBoxEdges),
                                     new THREE.LineBasicMaterial({ vertexColors: THREE.VertexColors }));
  world.add(leafMesh, leafEdges);
  viewer.drawnLeaves = leafMesh.geometry.attributes.position.count / 36;
}

// --- one leaf -------------------------------------------------------------------

function showLeafStats(i) {
  const rows = snapshot.columns.map((name, c) => '<tr><td>' + name + '</td><td>' + value(i, c).toPrecision(6) + '</td></tr>');
  const b = snapshot.leaves[i].box.map((x) => x.toPrecision(4));
  rows.unshift('<tr><td>leaf box</td><td>(' + b.slice(0, 3).join(', ') + ') - (' + b.slice(3).join(', ') + ')</td></tr>');
  ui('leafstats').innerHTML = rows.join('');
}

// The learned distribution on a sphere at the leaf's centre, textured with the map (u: phi, v: cos theta).
function placeSphere(i, mapCanvas) {
  if (sphere) world.remove(sphere), sphere.geometry.dispose();
  const b = snapshot.leaves[i].box;
  const radius = 0.3 * Math.min(b[3] - b[0], b[4] - b[1], b[5] - b[2]);
  const g = new THREE.SphereBufferGeometry(1, 64, 32), p = g.attributes.position, uv = g.attributes.uv;
  for (let k = 0; k < p.count; ++k) {
    let phi = Math.atan2(p.getY(k), p.getX(k));
    if (phi < 0) phi += 2 * Math.PI;
    uv.setXY(k, phi / (2 * Math.PI), 0.5 * (p.getZ(k) + 1));
  }
  const texture = new THREE.CanvasTexture(mapCanvas);
  sphere = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ map: texture }));
  sphere.scale.setScalar(radius);
  sphere.position.set((b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2);
  world.add(sphere);
}

function selectLeaf(i) {
  viewer.selected = i;
  const leaf = snapshot.leaves[i], map = ui('map'), hist = ui('hist');
  ui('leaf').style.display = '';
  const learned = leaf.quadtree.length || (leaf.lobes && leaf.lobes.length);
  ui('leaftitle').textContent = 'leaf ' + i + (learned ? '' : ': learned nothing (no guiding here)') +
      (leaf.lobes && leaf.lobes.length ? ' (mixture, seen from the leaf\'s centre)' : '');
  drawMap(map, learnedMap(leaf, map.width, map.height));
  drawMap(hist, histogramMap(leaf, hist.width, hist.height, ui('weighted').checked));
  showLeafStats(i);
  if (selection) world.remove(selection);
  const b = leaf.box, g = new THREE.BoxBufferGeometry(b[3] - b[0], b[4] - b[1], b[5] - b[2]);
  selection = new THREE.LineSegments(new THREE.EdgesGeometry(g), new THREE.LineBasicMaterial({ color: 0xffffff }));
  selection.position.set((b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2);
  world.add(selection);
  placeSphere(i, map);
}

// --- page -----------------------------------------------------------------------

function loadSnapshot(k) {
  snapshot = F.snapshots[k];
  viewer.leafCount = snapshot.leaves.length;
  ui('iteration').textContent = snapshot.iteration + ' (' + snapshot.spp + ' spp, ' + snapshot.leaves.length + ' leaves)';
  const summary = Object.entries(snapshot.summary).map(([key, v]) => key + ' ' + v).join(', ');
  ui('carries').innerHTML = 'per leaf: ' + snapshot.columns.join(', ') + '<br>field: ' + summary +
      (snapshot.leaves.some((l) => l.lobes && l.lobes.length)
        ? '<br>per leaf also: its von Mises-Fisher mixture (lobes seen from a pivot), up to 256 recorded directions ' +
          'with their radiance / pdf.<br>The mixture field re-points each lobe towards its source from the lookup ' +
          'position (parallax), so a leaf\'s distribution changes within it: the map shows it at the leaf\'s centre.'
        : '<br>per leaf also: its quadtree, up to 256 recorded directions with their radiance / pdf.' +
          '<br>The SD-tree looks up one leaf per point (no parallax compensation, no stochastic lookup), so a leaf\'s ' +
          'distribution is the one the renderer samples anywhere in it.');
  buildLeaves();
  if (viewer.selected >= 0 && viewer.selected < snapshot.leaves.length) selectLeaf(viewer.selected);
}

// The pixel of the view where a leaf's drawn box centre projects (tests click there).
viewer.leafScreenPosition = (i) => {
  const b = drawnBox(i), p = new THREE.Vector3((b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2);
  p.applyMatrix4(world.matrixWorld).project(camera);
  const r = renderer.domElement.getBoundingClientRect();
  return { x: r.left + (p.x + 1) / 2 * r.width, y: r.top + (1 - p.y) / 2 * r.height, inside: Math.abs(p.z) <= 1 };
};
viewer.mapRect = () => { const r = ui('map').getBoundingClientRect(); return { x: r.left, y: r.top, width: r.width, height: r.height }; };
viewer.selectLeaf = selectLeaf;

function pick(event) {
  const r = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2((event.clientX - r.left) / r.width * 2 - 1, -((event.clientY - r.top) / r.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, camera);
  // The nearest box the ray enters: not one the eye is inside (faces are drawn from both sides).
  const eye = ray.ray.origin.clone().applyMatrix4(new THREE.Matrix4().getInverse(world.matrixWorld));
  for (const hit of leafMesh ? ray.intersectObject(leafMesh) : []) {
    const leaf = shown[Math.floor(hit.faceIndex / 12)], b = drawnBox(leaf);
    const inside = [0, 1, 2].every((a) => eye.getComponent(a) >= b[a] && eye.getComponent(a) <= b[a + 3]);
    if (!inside) return selectLeaf(leaf);
  }
}

function start() {
  const stat = ui('stat');
  F.snapshots[F.snapshots.length - 1].columns.forEach((name, c) => stat.add(new Option(name, c)));
  const preferred = F.snapshots[F.snapshots.length - 1].columns.indexOf('mean_radiance');
  if (preferred >= 0) stat.value = preferred;
  const timeline = ui('timeline');
  timeline.max = F.snapshots.length - 1;
  timeline.value = F.snapshots.length - 1;
  ui('info').innerHTML = F.snapshots.length + ' snapshot(s); scene wireframe: ' + bytes(F.wireframe).byteLength / 36 +
      ' of ' + F.scene_triangles + ' triangles';
  addWireframe();
  resize();
  renderCamera();
  loadSnapshot(F.snapshots.length - 1);
  timeline.addEventListener('input', () => loadSnapshot(Number(timeline.value)));
  for (const id of ['stat', 'logscale', 'seen', 'slice0', 'slice1', 'slice2']) ui(id).addEventListener('input', buildLeaves);
  ui('weighted').addEventListener('input', () => viewer.selected >= 0 && selectLeaf(viewer.selected));
  ui('reset').addEventListener('click', renderCamera);
  let down = null;
  renderer.domElement.addEventListener('pointerdown', (e) => (down = [e.clientX, e.clientY]));
  renderer.domElement.addEventListener('pointerup', (e) => {
    if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4) pick(e);
  });
  window.addEventListener('resize', resize);
  (function frame() {
    renderer.render(scene, camera);
    requestAnimationFrame(frame);
  })();
  viewer.ready = true;
}

try {
  if (!F || !F.snapshots || F.snapshots.length === 0) throw new Error('field.js holds no snapshot');
  start();
} catch (e) {
  report(e.stack || e);
}
