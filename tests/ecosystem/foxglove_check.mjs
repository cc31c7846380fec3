// Drives occgeod's Foxglove endpoint with @foxglove/ws-protocol's own client:
//   node foxglove_check.mjs OCCGEO_CLI SERVER_ADDRESS HTTP_PORT BAG WORK_DIR
// It checks that /map and /scans are advertised, subscribes to both, replays BAG into the server with the occgeo CLI,
// and checks the messages decode (foxglove.Grid and foxglove.PointCloud in JSON) and that the last /map equals the
// world's grid as `occgeo map export` writes it (same size and origin; each certainty drawn as one grey, greys
// darkening as certainty rises, never-observed cells unknown). Then it unsubscribes, replays again, and checks no
// message arrives. Prints one JSON summary; exits 1 on the first failed check.
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [cli, server, httpPort, bag, work] = process.argv.slice(2);
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
const fail = (what) => {
  console.error(`foxglove_check: ${what}`);
  process.exit(1);
};
const check = (condition, what) => condition || fail(what);
setTimeout(() => fail("did not finish within 120 s"), 120000).unref();

const client = new FoxgloveClient({
  ws: new WebSocket(`ws://127.0.0.1:${httpPort}/`, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]),
});
client.on("error", (error) => fail(`client error: ${error.message}`));
const channels = await new Promise((resolve) => client.on("advertise", resolve));
const byTopic = new Map(channels.map((c) => [c.topic, c]));
check(byTopic.has("/map") && byTopic.has("/scans"), `advertised ${[...byTopic.keys()].join(", ")}, not /map and /scans`);
check(byTopic.get("/map").schemaName === "foxglove.Grid", "/map is not a foxglove.Grid");

const received = { map: [], scans: [] };
const subscriptions = new Map();
client.on("message", ({ subscriptionId, data }) => {
  const text = new TextDecoder().decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
  received[subscriptions.get(subscriptionId)].push({ at: Date.now(), message: JSON.parse(text) });
});
subscriptions.set(client.subscribe(byTopic.get("/map").id), "map");
subscriptions.set(client.subscribe(byTopic.get("/scans").id), "scans");
await sleep(300);

const replay = (id) =>
  execFileSync(cli, ["replay", "--server", server, "--format", "mcap", bag, "--max", "--id", id], { stdio: "pipe" });
replay("foxglove-a");
await sleep(2500);  // /map is sent at most once a second
check(received.map.length > 0, "no /map message while subscribed");
check(received.scans.length > 0, "no /scans message while subscribed");

// /scans: float32 x, y per point in the world frame.
const scan = received.scans.at(-1).message;
const points = Buffer.from(scan.data, "base64");
check(scan.point_stride === 8 && points.length > 0 && points.length % 8 === 0, "a /scans message has no x,y points");
for (let i = 0; i < points.length; i += 8) {
  check(Number.isFinite(points.readFloatLE(i)) && Number.isFinite(points.readFloatLE(i + 4)), "a non-finite point");
}

// /map against `occgeo map export` (ROS map_server PGM: row 0 at the top; the grid's row 0 at the bottom).
const grid = received.map.at(-1).message;
const cells = Buffer.from(grid.data, "base64");
const width = grid.column_count;
const height = cells.length / width;
const prefix = path.join(work, "exported");
execFileSync(cli, ["map", "export", "--server", server, "--world", "default", "--out", prefix], { stdio: "pipe" });
const yaml = fs.readFileSync(`${prefix}.yaml`, "utf8");
const number = (key) => Number(new RegExp(`${key}:\\s*([-0-9.eE+]+)`).exec(yaml)[1]);
const origin = /origin:\s*\[\s*([-0-9.eE+]+)\s*,\s*([-0-9.eE+]+)/.exec(yaml).slice(1).map(Number);
const pgm = fs.readFileSync(`${prefix}.pgm`);
const header = /^P5\s+(\d+)\s+(\d+)\s+(\d+)\s/.exec(pgm.toString("latin1", 0, 64));
const [pgmWidth, pgmHeight] = [Number(header[1]), Number(header[2])];
const pixels = pgm.subarray(header[0].length);
check(pgmWidth === width && pgmHeight === height, `/map is ${width}x${height}, the export ${pgmWidth}x${pgmHeight}`);
check(Math.abs(number("resolution") - grid.cell_size.x) < 1e-9, "/map cell size differs from the export");
check(Math.abs(origin[0] - grid.pose.position.x) < 1e-6 && Math.abs(origin[1] - grid.pose.position.y) < 1e-6,
  `/map origin (${grid.pose.position.x}, ${grid.pose.position.y}) differs from the export's (${origin})`);
const greyOf = new Map();
let observed = 0;
for (let row = 0; row < height; ++row) {
  for (let col = 0; col < width; ++col) {
    const certainty = cells[row * width + col];
    const grey = pixels[(height - 1 - row) * width + col];
    if (certainty !== 255) ++observed;
    if (!greyOf.has(certainty)) greyOf.set(certainty, grey);
    check(greyOf.get(certainty) === grey, `certainty ${certainty} drawn as both ${greyOf.get(certainty)} and ${grey}`);
  }
}
const observedGreys = [...greyOf.entries()].filter(([c]) => c !== 255).sort((a, b) => a[0] - b[0]);
for (let i = 1; i < observedGreys.length; ++i) {
  check(observedGreys[i][1] < observedGreys[i - 1][1], "greys do not darken as certainty rises");
}
check(greyOf.size >= 3 && observed > 100, "the map has too few observed cells to compare");

// Unsubscribed, nothing more arrives even though the grid and the scans change.
for (const id of subscriptions.keys()) client.unsubscribe(id);
await sleep(300);
const unsubscribedAt = Date.now();
replay("foxglove-b");
await sleep(2500);
const late = [...received.map, ...received.scans].filter((m) => m.at > unsubscribedAt).length;
check(late === 0, `${late} message(s) after unsubscribing`);
client.close();
console.log(JSON.stringify({ map_messages: received.map.length, scan_messages: received.scans.length, width, height,
  observed_cells: observed, certainty_levels: greyOf.size, messages_after_unsubscribe: late }));
process.exit(0);
