// The viewer of `mobmap serve`: the map's surface voxels in mobility colours, the camera
// path, a click that asks the server about a voxel, and a refresh while a live map grows.
// Map frame: z up, metres. Query string: ?max=N caps the voxels drawn (default 300000;
// the server coarsens the grid to stay under it); ?click=FX,FY clicks at that point of
// the view (fractions of its width and height) once the map is drawn; ?level=K shows
// level K's elevation (GET /api/layer) instead of the voxels.
(function () {
  'use strict';

  const params = new URLSearchParams(window.location.search);
  const maxVoxels = Math.max(1, Math.min(2000000, parseInt(params.get('max') || '300000', 10) || 300000));
  const statusEl = document.getElementById('status');
  const titleEl = document.getElementById('title');
  const answerEl = document.getElementById('answer');
  const levelsEl = document.getElementById('levels');
  const elevationLegendEl = document.getElementById('elevation-legend');

  // The mobility colours, as the server's pictures draw them (GET /api/colours): evenly
  // spaced stops from mobility 0 to 1, linear between them; unknown in its own colour.
  let colourScale = { stops: [[68, 1, 84], [253, 231, 37]], unknown: [190, 190, 190] };
  function mobilityRgb(m) {
    if (m === null || !isFinite(m)) return colourScale.unknown;
    const stops = colourScale.stops;
    const at = Math.min(1, Math.max(0, m)) * (stops.length - 1);
    const i = Math.min(Math.floor(at), stops.length - 2);
    const f = at - i;
    return [0, 1, 2].map(function (c) { return Math.round((1 - f) * stops[i][c] + f * stops[i + 1][c]); });
  }
  function setColours(scale) {
    colourScale = scale;
    const css = function (c) { return 'rgb(' + c[0] + ',' + c[1] + ',' + c[2] + ')'; };
    document.getElementById('mobility-bar').style.background =
      'linear-gradient(to right, ' + scale.stops.map(css).join(', ') + ')';
    document.getElementById('unknown-swatch').style.background = css(scale.unknown);
  }

  // --- scene --------------------------------------------------------------------------
  const container = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.setClearColor(0x1b1d22);
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, 0.02, 2000);
  camera.up.set(0, 0, 1);  // the map frame's z is up
  camera.position.set(-4, -6, 5);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.addEventListener('change', render);

  let frameRequested = false;
  function render() {
    if (frameRequested) return;
    frameRequested = true;
    requestAnimationFrame(function () {
      frameRequested = false;
      renderer.render(scene, camera);
    });
  }
  window.addEventListener('resize', function () {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    render();
  });

  // Voxels: one cube drawn many times (instancing), placed and coloured per voxel;
  // faces shaded by their direction so that walls and floors read apart.
  const cube = new THREE.BoxBufferGeometry(1, 1, 1);
  const material = new THREE.ShaderMaterial({
    uniforms: { cellSize: { value: 0.02 } },
    vertexShader: [
      'uniform float cellSize;',
      'attribute vec3 offset;',
      'attribute vec3 colour;',
      'varying vec3 vColour;',
      'void main() {',
      '  float shade = normal.z > 0.5 ? 1.0 : (normal.z < -0.5 ? 0.5 : (abs(normal.x) > 0.5 ? 0.8 : 0.66));',
      '  vColour = colour * shade;',
      '  vec3 p = offset + position * cellSize;',
      '  gl_Position = projectionMatrix * modelViewMatrix * vec4(p, 1.0);',
      '}'].join('\n'),
    fragmentShader: [
      'varying vec3 vColour;',
      'void main() { gl_FragColor = vec4(vColour, 1.0); }'].join('\n'),
  });
  let voxelMesh = null;
  let pathLine = null;
  let pathHead = null;
  const picked = new THREE.LineSegments(new THREE.EdgesGeometry(cube), new THREE.LineBasicMaterial({ color: 0xffffff }));
  picked.visible = false;
  scene.add(picked);

  // What is drawn: cell index -> voxel, for clicks.
  let grid = { size: 0.02, cells: new Map(), min: null, max: null };
  function cellKey(i, j, k) { return i + ',' + j + ',' + k; }

  function setVoxels(voxels, cellSize) {
    const n = voxels.length / 4;
    const offsets = new Float32Array(n * 3);
    const colours = new Uint8Array(n * 3);
    const cells = new Map();
    const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
    for (let v = 0; v < n; ++v) {
      for (let a = 0; a < 3; ++a) {
        const c = voxels[4 * v + a];
        offsets[3 * v + a] = c;
        min[a] = Math.min(min[a], c - cellSize / 2);
        max[a] = Math.max(max[a], c + cellSize / 2);
      }
      const rgb = mobilityRgb(voxels[4 * v + 3]);
      colours[3 * v] = rgb[0]; colours[3 * v + 1] = rgb[1]; colours[3 * v + 2] = rgb[2];
      cells.set(cellKey(Math.floor(voxels[4 * v] / cellSize), Math.floor(voxels[4 * v + 1] / cellSize),
                        Math.floor(voxels[4 * v + 2] / cellSize)), v);
    }
    if (voxelMesh) { scene.remove(voxelMesh); voxelMesh.geometry.dispose(); voxelMesh = null; }
    if (n > 0) {
      const g = new THREE.InstancedBufferGeometry();
      g.setIndex(cube.index);
      g.setAttribute('position', cube.attributes.position);
      g.setAttribute('normal', cube.attributes.normal);
      g.setAttribute('offset', new THREE.InstancedBufferAttribute(offsets, 3));
      g.setAttribute('colour', new THREE.InstancedBufferAttribute(colours, 3, true));
      g.maxInstancedCount = n;
      voxelMesh = new THREE.Mesh(g, material);
      voxelMesh.frustumCulled = false;  // the unit cube's bounds are not the map's
      scene.add(voxelMesh);
    }
    material.uniforms.cellSize.value = cellSize;
    grid = { size: cellSize, cells: cells, voxels: voxels, min: n ? min : null, max: n ? max : null };
  }

  function setPath(positions) {
    if (pathLine) { scene.remove(pathLine); pathLine.geometry.dispose(); pathLine = null; }
    if (pathHead) { scene.remove(pathHead); pathHead = null; }
    if (positions.length === 0) return;
    const flat = new Float32Array(positions.length * 3);
    positions.forEach(function (p, i) { flat[3 * i] = p[0]; flat[3 * i + 1] = p[1]; flat[3 * i + 2] = p[2]; });
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(flat, 3));
    pathLine = new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0x33aaff }));
    scene.add(pathLine);
    const last = positions[positions.length - 1];
    pathHead = new THREE.Mesh(new THREE.SphereBufferGeometry(Math.max(0.03, grid.size), 12, 8),
                              new THREE.MeshBasicMaterial({ color: 0x33aaff }));
    pathHead.position.set(last[0], last[1], last[2]);
    scene.add(pathHead);
  }

  // A level's elevation (GET /api/layer): each cell a flat tile at its height, coloured
  // from blue (the level's lowest) to yellow (its highest), tiles of one height shaded
  // alike so that steps read as edges. The voxels are hidden while it is shown.
  let levelMesh = null;
  let shownLevel = null;
  function elevationRgb(t) {
    t = Math.min(1, Math.max(0, t));
    return [Math.round(40 + 210 * t), Math.round(80 + 140 * t), Math.round(220 - 180 * t)];
  }
  function setLevel(layer) {
    if (levelMesh) { scene.remove(levelMesh); levelMesh.geometry.dispose(); levelMesh = null; }
    let lo = Infinity, hi = -Infinity, n = 0;
    layer.elevation.forEach(function (row) {
      row.forEach(function (e) { if (e !== null) { lo = Math.min(lo, e); hi = Math.max(hi, e); ++n; } });
    });
    const positions = new Float32Array(n * 18), colours = new Float32Array(n * 18);
    const s = layer.cell_m;
    let at = 0;
    for (let r = 0; r < layer.rows; ++r) {
      for (let c = 0; c < layer.cols; ++c) {
        const e = layer.elevation[r][c];
        if (e === null) continue;
        const x0 = layer.x_min + c * s, y0 = layer.y_min + (layer.rows - 1 - r) * s;
        const rgb = elevationRgb(hi > lo ? (e - lo) / (hi - lo) : 0);
        const corners = [[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0], [x0 + s, y0 + s], [x0, y0 + s]];
        corners.forEach(function (p) {
          positions[at] = p[0]; positions[at + 1] = p[1]; positions[at + 2] = e;
          colours[at] = rgb[0] / 255; colours[at + 1] = rgb[1] / 255; colours[at + 2] = rgb[2] / 255;
          at += 3;
        });
      }
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    g.setAttribute('color', new THREE.BufferAttribute(colours, 3));
    levelMesh = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide }));
    scene.add(levelMesh);
    if (voxelMesh) voxelMesh.visible = false;
    shownLevel = layer.level;
    elevationLegendEl.style.display = 'block';
    document.getElementById('elevation-low').textContent = n ? lo.toFixed(2) : '';
    document.getElementById('elevation-high').textContent = n ? hi.toFixed(2) + ' m' : '';
    statusEl.textContent = 'level ' + layer.level + ' at z = ' + layer.z_m.toFixed(2) + ' m: ' + n + ' cells of ' +
                           (s * 100).toFixed(0) + ' cm';
    render();
  }
  function showVoxels() {
    if (levelMesh) { scene.remove(levelMesh); levelMesh.geometry.dispose(); levelMesh = null; }
    if (voxelMesh) voxelMesh.visible = true;
    shownLevel = null;
    elevationLegendEl.style.display = 'none';
    render();
  }
  function listLevels(levels) {
    levelsEl.textContent = '';
    const add = function (label, onClick) {
      const a = document.createElement('a');
      a.href = '#';
      a.textContent = label;
      a.style.marginRight = '8px';
      a.addEventListener('click', function (e) { e.preventDefault(); onClick(); });
      levelsEl.appendChild(a);
    };
    add('voxels', showVoxels);
    levels.forEach(function (l) {
      add('level ' + l.index + ' (z ' + l.z_m.toFixed(2) + ')', function () { loadLevel(l.index); });
    });
  }
  function loadLevel(k) {
    return getJson('api/layer?level=' + k).then(function (layer) {
      listLevels(layer.levels);
      if (layer.level === null) return;
      setLevel(layer);
      // Tests wait for this: the level is drawn.
      requestAnimationFrame(function () { document.body.setAttribute('data-drawn-level', String(layer.level)); });
    }).catch(function (e) {
      statusEl.textContent = 'error: ' + e.message;
    });
  }

  // The first time there is something to see: look at it from above and behind.
  let framed = false;
  function frameView() {
    if (framed || !grid.min) return;
    framed = true;
    const c = new THREE.Vector3((grid.min[0] + grid.max[0]) / 2, (grid.min[1] + grid.max[1]) / 2,
                                (grid.min[2] + grid.max[2]) / 2);
    const d = Math.max(1, Math.hypot(grid.max[0] - grid.min[0], grid.max[1] - grid.min[1], grid.max[2] - grid.min[2]));
    controls.target.copy(c);
    camera.position.set(c.x - 0.45 * d, c.y - 0.75 * d, c.z + 0.75 * d);
    camera.near = d / 500;
    camera.far = d * 20;
    camera.updateProjectionMatrix();
    controls.update();
  }

  // --- the server -----------------------------------------------------------------------
  function getJson(url) {
    return fetch(url).then(function (r) {
      return r.json().then(function (j) {
        if (!r.ok) throw new Error(j.error || ('HTTP ' + r.status));
        return j;
      });
    });
  }
  function postJson(url, body) {
    return fetch(url, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) })
      .then(function (r) { return r.json(); });
  }

  // All pages of the voxels at the finest grid with at most maxVoxels cells.
  function loadVoxels() {
    let all = [];
    let head = null;
    function page(offset) {
      let url = 'api/voxels?max=' + maxVoxels + '&offset=' + offset;
      if (head) url += '&level=' + head.level;  // the level of the first page, for every page
      return getJson(url).then(function (j) {
        if (!head) head = j;
        all = all.concat(j.voxels);
        return j.next === null ? { head: head, voxels: all } : page(j.next);
      });
    }
    return page(0);
  }

  let shownFrames = -1;
  let shownBuilding = null;
  let loading = false;
  function describe(info, head) {
    const parts = [];
    parts.push(head.total + ' surface voxels' + (head.level > 0 ? ' (' + (head.cell_size_m * 100).toFixed(0) +
               ' cm cells, coarsened from ' + (info.resolution_m * 100).toFixed(0) + ' cm)' : ' of ' +
               (info.resolution_m * 100).toFixed(0) + ' cm'));
    parts.push(info.frames + ' frames' + (info.building ? ', building...' : ''));
    return parts.join('; ');
  }

  function refresh() {
    if (loading) return;
    loading = true;
    const coloured = colourScale.scale ? Promise.resolve() : getJson('api/colours').then(setColours);
    coloured.then(function () { return getJson('api/info'); }).then(function (info) {
      titleEl.textContent = info.map;
      document.title = 'mobmap: ' + info.map;
      if (info.frames === shownFrames && info.building === shownBuilding) return null;
      return Promise.all([loadVoxels(), getJson('api/camera_path')]).then(function (got) {
        const v = got[0];
        setVoxels(v.voxels, v.head.cell_size_m);
        setPath(got[1].positions);
        frameView();
        shownFrames = v.head.frames;
        shownBuilding = v.head.building;
        statusEl.textContent = describe(info, v.head);
        if (voxelMesh && shownLevel !== null) voxelMesh.visible = false;
        render();
        const asked = params.get('level');
        if (asked !== null && !levelAsked) {
          levelAsked = true;
          loadLevel(parseInt(asked, 10) || 0);
        } else if (!levelAsked) {
          levelAsked = true;
          getJson('api/layer?max=1').then(function (layer) { listLevels(layer.levels); }).catch(function () {});
        }
        // Tests wait for this: the map is drawn.
        requestAnimationFrame(function () {
          document.body.setAttribute('data-drawn-frames', String(shownFrames));
          clickIfAsked();
        });
      });
    }).catch(function (e) {
      statusEl.textContent = 'error: ' + e.message;
    }).then(function () {
      loading = false;
      // A live map is looked at again while it grows; a finished one is left alone.
      if (shownBuilding !== false) setTimeout(refresh, 1000);
    });
  }

  // --- clicks -----------------------------------------------------------------------------
  // The first drawn cell along the ray (a grid walk, one cell at a time).
  function firstCell(ray) {
    if (!grid.min) return null;
    const s = grid.size;
    const o = ray.origin.toArray(), d = ray.direction.toArray();
    // Enter the map's box first.
    let t0 = 0, t1 = Infinity;
    for (let a = 0; a < 3; ++a) {
      if (Math.abs(d[a]) < 1e-12) {
        if (o[a] < grid.min[a] || o[a] > grid.max[a]) return null;
        continue;
      }
      let ta = (grid.min[a] - o[a]) / d[a], tb = (grid.max[a] - o[a]) / d[a];
      if (ta > tb) { const t = ta; ta = tb; tb = t; }
      t0 = Math.max(t0, ta); t1 = Math.min(t1, tb);
    }
    if (t0 > t1) return null;
    const p = [o[0] + d[0] * t0, o[1] + d[1] * t0, o[2] + d[2] * t0];
    const cell = p.map(function (x, a) { return Math.floor(x / s - (d[a] < 0 ? 1e-9 : -1e-9)); });
    const step = d.map(function (x) { return x > 0 ? 1 : -1; });
    const tMax = [0, 1, 2].map(function (a) {
      if (d[a] === 0) return Infinity;
      const edge = (cell[a] + (d[a] > 0 ? 1 : 0)) * s;
      return t0 + (edge - p[a]) / d[a];
    });
    const tDelta = d.map(function (x) { return x === 0 ? Infinity : s / Math.abs(x); });
    for (let n = 0; n < 100000; ++n) {
      const v = grid.cells.get(cellKey(cell[0], cell[1], cell[2]));
      if (v !== undefined) return v;
      const a = tMax[0] < tMax[1] ? (tMax[0] < tMax[2] ? 0 : 2) : (tMax[1] < tMax[2] ? 1 : 2);
      if (tMax[a] > t1) return null;
      cell[a] += step[a];
      tMax[a] += tDelta[a];
    }
    return null;
  }

  function fmt(x, digits) { return x === null || x === undefined ? 'unknown' : Number(x).toFixed(digits); }

  // Asks the server about the voxel under the pixel (clientX, clientY) and shows the
  // answer; resolves to {centre, answer} (null: no voxel there).
  function pick(clientX, clientY) {
    const rect = renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    const raycaster = new THREE.Raycaster();
    raycaster.setFromCamera(ndc, camera);
    const v = firstCell(raycaster.ray);
    if (v === null) {
      picked.visible = false;
      answerEl.style.display = 'none';
      render();
      return Promise.resolve(null);
    }
    const c = [grid.voxels[4 * v], grid.voxels[4 * v + 1], grid.voxels[4 * v + 2]];
    picked.position.set(c[0], c[1], c[2]);
    picked.scale.setScalar(grid.size * 1.02);
    picked.visible = true;
    render();
    // The voxel's answer, and a sole of the default size centred on its top.
    const top = c[2] + grid.size / 2;
    return Promise.all([
      postJson('api/query', { points: [c] }),
      postJson('api/foot', { soles: [[c[0], c[1], top, 0, 0.25, 0.12]] }),
    ]).then(function (r) {
      const q = r[0].answers ? r[0].answers[0] : r[0];
      const f = r[1].answers ? r[1].answers[0] : r[1];
      const lines = ['voxel at (' + c.map(function (x) { return x.toFixed(3); }).join(', ') + ') m, map frame'];
      if (q.error) {
        lines.push('error: ' + q.error);
      } else {
        lines.push('state      ' + q.state);
        lines.push('mobility   ' + fmt(q.mobility, 3) + (q.variance !== null && q.variance !== undefined ? '  (variance ' + fmt(q.variance, 4) + ')' : ''));
        lines.push('seen       ' + q.count + ' times');
      }
      if (f && !f.error) {
        lines.push('a 25 x 12 cm sole here: min mobility ' + fmt(f.min_mobility, 2) + ', known ' + fmt(100 * f.known_fraction, 0) + ' %');
        if (f.support_plane) lines.push('  support tilt ' + fmt(f.support_plane.tilt_deg, 1) + ' deg');
      }
      answerEl.textContent = lines.join('\n');
      answerEl.style.display = 'block';
      return { centre: c, answer: q, sole: f };
    });
  }

  const down = { x: 0, y: 0 };
  renderer.domElement.addEventListener('pointerdown', function (e) { down.x = e.clientX; down.y = e.clientY; });
  renderer.domElement.addEventListener('pointerup', function (e) {
    if (Math.hypot(e.clientX - down.x, e.clientY - down.y) > 4) return;  // a drag, not a click
    pick(e.clientX, e.clientY);
  });

  // ?click=FX,FY: once the map is drawn, click at that point of the view (fractions of its
  // width and height); the page records what it was told (data-picked), so that a test
  // can check a click without a mouse.
  const click = (params.get('click') || '').split(',').map(Number);
  let clicked = false;
  function clickIfAsked() {
    if (clicked || click.length !== 2 || !click.every(isFinite)) return;
    clicked = true;
    const rect = renderer.domElement.getBoundingClientRect();
    pick(rect.left + click[0] * rect.width, rect.top + click[1] * rect.height).then(function (r) {
      document.body.setAttribute('data-picked', JSON.stringify(r));
    });
  }

  let levelAsked = false;
  refresh();
})();
