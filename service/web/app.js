// occgeo live view: draws what occgeod believes, from the JSON frames of its /ws WebSocket.
// Everything is in the world frame (metres, radians, y up) until the last transform to canvas pixels.
'use strict';

const canvas = document.getElementById('map');
const ctx = canvas.getContext('2d');
const ROBOT_COLOUR = '#ff8c00';
const SCAN_COLOUR = '#00e640';
const PATH_COLOUR = '#2ec4b6';
// Scan points listed in the page summary per robot, at most (for tests and scripts checking where they were drawn).
const SUMMARY_SCAN_POINTS = 24;

const view = {
  world: null,
  map: null,              // the latest frame's map header (version, cell size, threshold ...)
  tiles: new Map(),       // "tx,ty" -> {tx, ty, cells: Uint8Array, image: canvas}
  robots: [],
  ptem: {clusters: []},
  slice: null,
  frames: 0,
  socket: null,
};

function tileImage(cells, n, threshold, maxCertainty) {
  const image = document.createElement('canvas');
  image.width = n;
  image.height = n;
  const g = image.getContext('2d');
  const pixels = g.createImageData(n, n);
  for (let row = 0; row < n; ++row) {
    // Row 0 of the tile is its south edge: draw it at the bottom of the image.
    const out = (n - 1 - row) * n;
    for (let col = 0; col < n; ++col) {
      const c = cells[row * n + col];
      const k = (out + col) * 4;
      if (c === 255) {
        pixels.data[k + 3] = 0;  // unobserved: the canvas background shows
        continue;
      }
      const grey = c >= threshold ? 0 : Math.round(255 - 110 * c / Math.max(1, threshold));
      pixels.data[k] = pixels.data[k + 1] = pixels.data[k + 2] = grey;
      pixels.data[k + 3] = 255;
    }
  }
  g.putImageData(pixels, 0, 0);
  return image;
}

// [first column, first row, last column, last row] of the observed cells of a tile; null when none is.
function observedBox(cells, n) {
  let c0 = n, r0 = n, c1 = -1, r1 = -1;
  for (let i = 0; i < cells.length; ++i) {
    if (cells[i] === 255) continue;
    const col = i % n, row = Math.floor(i / n);
    c0 = Math.min(c0, col); c1 = Math.max(c1, col); r0 = Math.min(r0, row); r1 = Math.max(r1, row);
  }
  return c1 < 0 ? null : [c0, r0, c1, r1];
}

function decodeBase64(text) {
  const raw = atob(text);
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; ++i) bytes[i] = raw.charCodeAt(i);
  return bytes;
}

// World metres -> canvas pixels: the observed tiles and the robots fitted into the canvas, north up.
function computeTransform() {
  let minX = Infinity, minY = Infinity, maxX = -Infinity, maxY = -Infinity;
  const grow = (x, y) => {
    minX = Math.min(minX, x); minY = Math.min(minY, y); maxX = Math.max(maxX, x); maxY = Math.max(maxY, y);
  };
  if (view.map) {
    const side = view.map.tile_cells * view.map.cell_size_m;
    const cell = view.map.cell_size_m;
    for (const tile of view.tiles.values()) {
      if (!tile.observed) continue;
      const [c0, r0, c1, r1] = tile.observed;
      grow(tile.tx * side + c0 * cell, tile.ty * side + r0 * cell);
      grow(tile.tx * side + (c1 + 1) * cell, tile.ty * side + (r1 + 1) * cell);
    }
  }
  for (const robot of view.robots) {
    if (robot.world === view.world && robot.pose) grow(robot.pose.x, robot.pose.y);
    // Where a robot is heading stays in view.
    if (robot.world === view.world && robot.path) for (const [x, y] of robot.path) grow(x, y);
  }
  if (!isFinite(minX)) { minX = -5; minY = -5; maxX = 5; maxY = 5; }
  const margin = 1.0;
  minX -= margin; minY -= margin; maxX += margin; maxY += margin;
  const scale = Math.min(canvas.width / (maxX - minX), canvas.height / (maxY - minY));
  const offsetX = (canvas.width - scale * (maxX - minX)) / 2;
  const offsetY = (canvas.height - scale * (maxY - minY)) / 2;
  return {
    scale,
    x: (wx) => offsetX + (wx - minX) * scale,
    y: (wy) => canvas.height - offsetY - (wy - minY) * scale,
  };
}

function footprintCorners(robot) {
  const f = robot.footprint;
  if (!f || (f.shape !== 'box' && f.shape !== 'polygon')) return null;
  const c = Math.cos(robot.pose.theta), s = Math.sin(robot.pose.theta);
  const hl = f.length_m / 2, hw = f.width_m / 2, cx = f.center_x_m;
  const outline = f.shape === 'polygon' ? f.vertices_m : [[cx + hl, hw], [cx - hl, hw], [cx - hl, -hw], [cx + hl, -hw]];
  return outline.map(
      ([bx, by]) => [robot.pose.x + c * bx - s * by, robot.pose.y + s * bx + c * by]);
}

function draw() {
  const t = computeTransform();
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  let occupiedRendered = 0;
  if (view.map && document.getElementById('show-grid').checked) {
    const n = view.map.tile_cells;
    const side = n * view.map.cell_size_m;
    ctx.imageSmoothingEnabled = false;
    for (const tile of view.tiles.values()) {
      const x0 = t.x(tile.tx * side), y0 = t.y((tile.ty + 1) * side);
      const x1 = t.x((tile.tx + 1) * side), y1 = t.y(tile.ty * side);
      ctx.drawImage(tile.image, x0, y0, x1 - x0, y1 - y0);
      for (const c of tile.cells) if (c !== 255 && c >= view.map.occupied_threshold) ++occupiedRendered;
    }
  }
  if (view.slice && document.getElementById('show-octomap').checked) {
    ctx.fillStyle = 'rgba(40, 110, 255, 0.7)';
    for (const [x, y, size] of view.slice.voxels) {
      ctx.fillRect(t.x(x - size / 2), t.y(y + size / 2), size * t.scale, size * t.scale);
    }
  }
  if (document.getElementById('show-ptem').checked) {
    for (const [x, y, r, reachable] of view.ptem.clusters) {
      ctx.beginPath();
      ctx.arc(t.x(x), t.y(y), r * t.scale, 0, 2 * Math.PI);
      ctx.fillStyle = reachable ? 'rgba(230, 40, 40, 0.25)' : 'rgba(230, 40, 40, 0.45)';
      ctx.fill();
      ctx.strokeStyle = 'rgb(230, 40, 40)';
      ctx.lineWidth = 1;
      ctx.stroke();
    }
  }
  // Scans and paths first, so every robot's footprint stays on top of them.
  const showScans = document.getElementById('show-scan').checked;
  const scanSummaries = new Map();
  for (const robot of view.robots) {
    if (robot.world !== view.world || !robot.scan || !showScans) continue;
    // Each return as a 3 x 3 pixel square centred on its end point.
    ctx.fillStyle = SCAN_COLOUR;
    const points = robot.scan.points;
    const sample = [];
    const every = Math.max(1, Math.ceil(points.length / SUMMARY_SCAN_POINTS));
    points.forEach(([x, y], i) => {
      const px = Math.round(t.x(x)), py = Math.round(t.y(y));
      ctx.fillRect(px - 1, py - 1, 3, 3);
      if (i % every === 0) sample.push([x, y, px, py]);
    });
    scanSummaries.set(robot.id, {stamp_s: robot.scan.stamp_s, points: points.length, sample});
  }
  const pathSummaries = new Map();
  for (const robot of view.robots) {
    if (robot.world !== view.world || !robot.path || robot.path.length < 2) continue;
    ctx.beginPath();
    robot.path.forEach(([x, y], i) => (i ? ctx.lineTo(t.x(x), t.y(y)) : ctx.moveTo(t.x(x), t.y(y))));
    ctx.strokeStyle = PATH_COLOUR;
    ctx.lineWidth = 3;
    ctx.stroke();
    pathSummaries.set(robot.id, robot.path.map(([x, y]) => [x, y, t.x(x), t.y(y)]));
  }
  const drawnRobots = [];
  for (const robot of view.robots) {
    if (robot.world !== view.world || !robot.pose) continue;
    const px = t.x(robot.pose.x), py = t.y(robot.pose.y);
    const corners = footprintCorners(robot);
    ctx.beginPath();
    if (corners) {
      corners.forEach(([x, y], i) => (i ? ctx.lineTo(t.x(x), t.y(y)) : ctx.moveTo(t.x(x), t.y(y))));
      ctx.closePath();
    } else {
      const radius = robot.footprint && robot.footprint.radius_m ? robot.footprint.radius_m : 0.3;
      ctx.arc(px, py, Math.max(3, radius * t.scale), 0, 2 * Math.PI);
    }
    ctx.fillStyle = robot.estop ? '#c62828' : ROBOT_COLOUR;
    ctx.fill();
    ctx.strokeStyle = '#222';
    ctx.lineWidth = 1;
    ctx.stroke();
    // Heading: a tick from the front edge outwards, so the pose's own pixel keeps the robot's colour.
    const c = Math.cos(robot.pose.theta), s = Math.sin(robot.pose.theta);
    const f = robot.footprint;
    const reach = f && f.shape === 'polygon' ? Math.max(...f.vertices_m.map(([x]) => x))
                : f && f.length_m ? f.length_m / 2 : 0.3;
    ctx.beginPath();
    ctx.moveTo(t.x(robot.pose.x + c * reach), t.y(robot.pose.y + s * reach));
    ctx.lineTo(t.x(robot.pose.x + c * (reach + 0.4)), t.y(robot.pose.y + s * (reach + 0.4)));
    ctx.strokeStyle = '#1565c0';
    ctx.lineWidth = 2;
    ctx.stroke();
    ctx.fillStyle = '#1565c0';
    ctx.font = 'bold 12px sans-serif';
    ctx.fillText(robot.id, px + 10, py - 10);
    drawnRobots.push({id: robot.id, x: robot.pose.x, y: robot.pose.y, theta: robot.pose.theta, px, py,
                      scan: scanSummaries.get(robot.id) || null, path: pathSummaries.get(robot.id) || []});
  }
  document.getElementById('summary').textContent = JSON.stringify({
    world: view.world,
    map_version: view.map ? view.map.version : null,
    map_complete: view.map ? view.map.map_complete : false,
    tiles: view.tiles.size,
    occupied_cells_rendered: occupiedRendered,
    occupied_cells_server: view.map ? view.map.occupied_cells : null,
    ptem_clusters: view.ptem.clusters.length,
    robots: drawnRobots,
    canvas: {width: canvas.width, height: canvas.height,
             left: Math.round(canvas.getBoundingClientRect().left + window.scrollX) + canvas.clientLeft,
             top: Math.round(canvas.getBoundingClientRect().top + window.scrollY) + canvas.clientTop},
    frames: view.frames,
  });
}

function text(value) { return value === undefined || value === null || value === '' ? '—' : String(value); }

function updatePanel() {
  const select = document.getElementById('world');
  const names = view.worlds || [];
  if (select.options.length !== names.length || names.some((n, i) => select.options[i].value !== n)) {
    select.replaceChildren(...names.map((n) => new Option(n, n)));
  }
  select.value = view.world;
  const info = document.getElementById('world-info');
  info.textContent = view.map
      ? `world ${view.world}: version ${view.map.version}, ${view.map.occupied_cells} occupied cells, ` +
        `${view.ptem.clusters.length} PTEM clusters` + (view.slice ? `, OctoMap slice z=${view.slice.z_m} m` : '')
      : `world ${view.world}: no map`;
  const body = document.querySelector('#robots tbody');
  body.replaceChildren(...view.robots.map((robot) => {
    const row = document.createElement('tr');
    const pose = robot.pose
        ? `${robot.pose.x.toFixed(2)}, ${robot.pose.y.toFixed(2)}, ${robot.pose.theta.toFixed(2)}` : '—';
    const state = [robot.connected ? 'connected' : 'offline', robot.behaviour_state,
                   robot.sensor_stale ? 'sensor stale' : '', robot.estop ? 'E-STOP' : '',
                   robot.lease_holder ? `lease: ${robot.lease_holder}` : ''].filter((s) => s).join(', ');
    for (const cell of [`${robot.id} (${robot.world})`, pose, robot.behaviour, state, text(robot.guard)]) {
      const td = document.createElement('td');
      td.textContent = cell;
      row.appendChild(td);
    }
    const td = document.createElement('td');
    const button = document.createElement('button');
    button.className = 'estop';
    button.textContent = 'E-STOP';
    button.disabled = robot.estop;
    button.onclick = () => send({type: 'estop', robot: robot.id});
    td.appendChild(button);
    row.appendChild(td);
    return row;
  }));
}

function onFrame(frame) {
  view.frames += 1;
  view.worlds = frame.worlds;
  if (frame.world !== view.world) {
    view.world = frame.world;
    view.tiles.clear();
    view.slice = null;
  }
  view.robots = frame.robots;
  view.map = frame.map;
  if (frame.map) {
    for (const tile of frame.map.tiles) {
      const cells = decodeBase64(tile.cells);
      view.tiles.set(`${tile.tx},${tile.ty}`, {
        tx: tile.tx, ty: tile.ty, cells, observed: observedBox(cells, frame.map.tile_cells),
        image: tileImage(cells, frame.map.tile_cells, frame.map.occupied_threshold, frame.map.max_certainty),
      });
    }
  }
  if (frame.ptem) view.ptem = frame.ptem;
  if (frame.octomap_slice) view.slice = frame.octomap_slice;
  draw();
  updatePanel();
}

function send(message) {
  if (view.socket && view.socket.readyState === WebSocket.OPEN) view.socket.send(JSON.stringify(message));
}

function connect() {
  const status = document.getElementById('connection');
  // The page's own token (a server reachable beyond loopback needs one) goes with its WebSocket.
  const token = new URLSearchParams(location.search).get("token");
  const socket = new WebSocket(`ws://${location.host}/ws` + (token ? `?token=${encodeURIComponent(token)}` : ""));
  view.socket = socket;
  socket.onopen = () => {
    status.textContent = 'live';
    status.className = 'ok';
    send({type: 'select', slice_z_m: Number(document.getElementById('slice-z').value)});
  };
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.type === 'frame') {
      onFrame(message);
    } else if (message.type === 'error') {
      document.getElementById('message').textContent = `server: ${message.field}: ${message.message}`;
    } else if (message.type === 'estop') {
      document.getElementById('message').textContent = `e-stop engaged on ${message.robot}`;
    }
  };
  socket.onclose = () => {
    status.textContent = 'disconnected, retrying…';
    status.className = 'bad';
    setTimeout(connect, 1000);
  };
}

document.getElementById('world').onchange = (event) => send({type: 'select', world: event.target.value});
document.getElementById('slice-z').onchange = (event) => send({type: 'select', slice_z_m: Number(event.target.value)});
for (const id of ['show-grid', 'show-ptem', 'show-octomap', 'show-scan']) document.getElementById(id).onchange = draw;
draw();
connect();
