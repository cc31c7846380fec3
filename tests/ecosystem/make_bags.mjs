// Writes ROS 2 bags (MCAP, CDR) from the recorded datasets with the MCAP ecosystem's own libraries, so occgeo's
// reader is checked against what real tools write rather than against our own writer.
//   node make_bags.mjs DATASETS_DIR OUT_DIR
// Writes intel-{none,zstd,lz4}.mcap (CARMEN Intel log: LaserScan + Odometry), exp1-zstd.mcap (URG exp1.dat:
// LaserScan + TF, no Odometry topic) and bunny-lz4.mcap (bun0.pcd as one PointCloud2 beside a short LaserScan stream).
import fs from "node:fs";
import path from "node:path";
import zlib from "node:zlib";
import { McapWriter } from "@mcap/core";
import { parse as parseMessageDefinition } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";
import * as zstd from "@foxglove/wasm-zstd";
import lz4 from "lz4js";

const SEPARATOR = "\n================================================================================\n";
const TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec";
const HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id";
const VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z";
const POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z";
const QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1";
const DEFINITIONS = {
  "sensor_msgs/msg/LaserScan": [
    "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\n" +
      "float32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities",
    HEADER,
    TIME,
  ],
  "nav_msgs/msg/Odometry": [
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n" +
      "geometry_msgs/TwistWithCovariance twist",
    HEADER,
    TIME,
    "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance",
    "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    POINT,
    QUATERNION,
    "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance",
    "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    VECTOR3,
  ],
  "tf2_msgs/msg/TFMessage": [
    "geometry_msgs/TransformStamped[] transforms",
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n" +
      "geometry_msgs/Transform transform",
    HEADER,
    TIME,
    "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
    VECTOR3,
    QUATERNION,
  ],
  "sensor_msgs/msg/PointCloud2": [
    "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\n" +
      "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense",
    HEADER,
    TIME,
    "MSG: sensor_msgs/PointField\nuint8 FLOAT32 = 7\nstring name\nuint32 offset\nuint8 datatype\nuint32 count",
  ],
};

const COMPRESSORS = {
  none: undefined,
  zstd: (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) }),
  lz4: (data) => ({ compression: "lz4", compressedData: Uint8Array.from(lz4.compress(data)) }),
};

class MemoryWritable {
  chunks = [];
  size = 0n;
  position() {
    return this.size;
  }
  async write(buffer) {
    this.chunks.push(Buffer.from(buffer));
    this.size += BigInt(buffer.byteLength);
  }
}

class BagWriter {
  constructor(compression) {
    this.out = new MemoryWritable();
    this.writer = new McapWriter({
      writable: this.out,
      chunkSize: 256 * 1024,
      compressChunk: COMPRESSORS[compression],
      useChunks: true,
    });
    this.channels = new Map();
    this.sequence = 0;
  }
  async start() {
    await this.writer.start({ profile: "ros2", library: "occgeo ecosystem tests" });
  }
  async topic(topic, type) {
    const text = DEFINITIONS[type].join(SEPARATOR);
    const schemaId = await this.writer.registerSchema({
      name: type,
      encoding: "ros2msg",
      data: new TextEncoder().encode(text),
    });
    const channelId = await this.writer.registerChannel({
      topic,
      schemaId,
      messageEncoding: "cdr",
      metadata: new Map(),
    });
    const serializer = new MessageWriter(parseMessageDefinition(text, { ros2: true }));
    this.channels.set(topic, { channelId, serializer });
  }
  async write(topic, stampS, message) {
    const { channelId, serializer } = this.channels.get(topic);
    const time = BigInt(Math.round(stampS * 1e9));
    await this.writer.addMessage({
      channelId,
      sequence: this.sequence++,
      logTime: time,
      publishTime: time,
      data: serializer.writeMessage(message),
    });
  }
  async finish(file) {
    await this.writer.end();
    fs.writeFileSync(file, Buffer.concat(this.out.chunks));
  }
}

const stamp = (s) => ({ sec: Math.floor(s), nanosec: Math.round((s - Math.floor(s)) * 1e9) % 1000000000 });
const yawQuaternion = (yaw) => ({ x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) });
const zeros36 = () => new Array(36).fill(0);

// CARMEN FLASER lines of the Intel log: ranges at or past 81 m are "no return" (+inf, REP 117).
function intelScans(datasets) {
  const text = zlib.gunzipSync(fs.readFileSync(path.join(datasets, "carmen-intel/intel-corrected.log.gz"))).toString();
  const scans = [];
  for (const line of text.split("\n")) {
    const t = line.trim().split(/\s+/);
    if (t[0] !== "FLASER") continue;
    const n = Number(t[1]);
    const ranges = t.slice(2, 2 + n).map(Number);
    const [x, y, theta, , , , ts] = t.slice(2 + n, 9 + n).map(Number);
    scans.push({ ranges: ranges.map((r) => (r >= 81 ? Infinity : r)), x, y, theta, ts });
  }
  return scans;
}

async function writeIntel(datasets, out, compression) {
  const bag = new BagWriter(compression);
  await bag.start();
  await bag.topic("/odom", "nav_msgs/msg/Odometry");
  await bag.topic("/scan", "sensor_msgs/msg/LaserScan");
  for (const s of intelScans(datasets)) {
    const header = (frame) => ({ stamp: stamp(s.ts), frame_id: frame });
    await bag.write("/odom", s.ts, {
      header: header("odom"),
      child_frame_id: "base_link",
      pose: { pose: { position: { x: s.x, y: s.y, z: 0 }, orientation: yawQuaternion(s.theta) }, covariance: zeros36() },
      twist: { twist: { linear: { x: 0, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } }, covariance: zeros36() },
    });
    const n = s.ranges.length;
    const increment = n === 180 || n === 181 ? Math.PI / 180 : Math.PI / (n - 1);
    await bag.write("/scan", s.ts, {
      header: header("base_link"),
      angle_min: -Math.PI / 2,
      angle_max: -Math.PI / 2 + increment * (n - 1),
      angle_increment: increment,
      time_increment: 0,
      scan_time: 0.2,
      range_min: 0.05,
      range_max: 81,
      ranges: Float32Array.from(s.ranges),
      intensities: new Float32Array(0),
    });
  }
  await bag.finish(path.join(out, `intel-${compression}.mcap`));
}

// URG exp1.dat: us stamps, wheel ticks (2000 per revolution, 77 mm wheels, 330 mm axle) dead-reckoned into
// odom -> base_link on /tf, the laser 0.145 m ahead on /tf_static; 0-19 mm are error codes, sent as NaN (REP 117).
async function writeExp1(datasets, out, compression) {
  const bag = new BagWriter(compression);
  await bag.start();
  await bag.topic("/tf_static", "tf2_msgs/msg/TFMessage");
  await bag.topic("/tf", "tf2_msgs/msg/TFMessage");
  await bag.topic("/scan", "sensor_msgs/msg/LaserScan");
  const metresPerTick = (2 * Math.PI * 0.077) / 2000;
  const delta = (a, b) => {
    let d = (b - a) % 2 ** 32;
    if (d >= 2 ** 31) d -= 2 ** 32;
    if (d < -(2 ** 31)) d += 2 ** 32;
    return d;
  };
  let pose = { x: 0, y: 0, theta: 0 };
  let last;
  const fov = (240 * Math.PI) / 180;
  let first = true;
  for (const line of fs.readFileSync(path.join(datasets, "urg04lx-mines/exp1.dat"), "utf8").split("\n")) {
    const f = line.trim().split(/\s+/);
    if (f.length < 24 + 682) continue;
    const ts = Number(f[0]) * 1e-6;
    const ticks = [Number(f[2]), Number(f[3])];
    if (last) {
      const left = delta(last[0], ticks[0]) * metresPerTick;
      const right = delta(last[1], ticks[1]) * metresPerTick;
      const d = (left + right) / 2;
      const w = (right - left) / 0.33;
      if (Math.abs(w) < 1e-9) {
        pose = { x: pose.x + d * Math.cos(pose.theta), y: pose.y + d * Math.sin(pose.theta), theta: pose.theta };
      } else {
        const r = d / w;
        pose = {
          x: pose.x + r * (Math.sin(pose.theta + w) - Math.sin(pose.theta)),
          y: pose.y - r * (Math.cos(pose.theta + w) - Math.cos(pose.theta)),
          theta: pose.theta + w,
        };
      }
    }
    last = ticks;
    if (first) {
      first = false;
      await bag.write("/tf_static", ts, {
        transforms: [
          {
            header: { stamp: stamp(ts), frame_id: "base_link" },
            child_frame_id: "laser",
            transform: { translation: { x: 0.145, y: 0, z: 0.2 }, rotation: yawQuaternion(0) },
          },
        ],
      });
    }
    await bag.write("/tf", ts, {
      transforms: [
        {
          header: { stamp: stamp(ts), frame_id: "odom" },
          child_frame_id: "base_link",
          transform: { translation: { x: pose.x, y: pose.y, z: 0 }, rotation: yawQuaternion(pose.theta) },
        },
      ],
    });
    const ranges = f.slice(24, 24 + 682).map((mm) => (Number(mm) < 20 ? NaN : Number(mm) * 1e-3));
    await bag.write("/scan", ts, {
      header: { stamp: stamp(ts), frame_id: "laser" },
      angle_min: -fov / 2,
      angle_max: fov / 2,
      angle_increment: fov / 681,
      time_increment: 0,
      scan_time: 0.1,
      range_min: 0.02,
      range_max: 5.6,
      ranges: Float32Array.from(ranges),
      intensities: new Float32Array(0),
    });
  }
  await bag.finish(path.join(out, `exp1-${compression}.mcap`));
}

// bun0.pcd (ASCII, x y z first) as one PointCloud2 of 28-byte points, between the first Intel scans.
async function writeBunny(datasets, out, compression) {
  const lines = fs.readFileSync(path.join(datasets, "pcl-scans/bun0.pcd"), "utf8").split("\n");
  const start = lines.findIndex((l) => l.startsWith("DATA ascii")) + 1;
  const points = lines.slice(start).filter((l) => l.trim() !== "").map((l) => l.trim().split(/\s+/).map(Number));
  const step = 16;
  const data = new Uint8Array(points.length * step);
  const view = new DataView(data.buffer);
  points.forEach((p, i) => {
    for (let axis = 0; axis < 3; ++axis) view.setFloat32(i * step + axis * 4, p[axis] * 10, true);
    view.setFloat32(i * step + 12, 1, true);  // an "intensity" field the reader must skip
  });
  const bag = new BagWriter(compression);
  await bag.start();
  await bag.topic("/odom", "nav_msgs/msg/Odometry");
  await bag.topic("/scan", "sensor_msgs/msg/LaserScan");
  await bag.topic("/points", "sensor_msgs/msg/PointCloud2");
  const scans = intelScans(datasets).slice(0, 20);
  for (const [i, s] of scans.entries()) {
    const header = (frame) => ({ stamp: stamp(s.ts), frame_id: frame });
    await bag.write("/odom", s.ts, {
      header: header("odom"),
      child_frame_id: "base_link",
      pose: { pose: { position: { x: s.x, y: s.y, z: 0 }, orientation: yawQuaternion(s.theta) }, covariance: zeros36() },
      twist: { twist: { linear: { x: 0, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } }, covariance: zeros36() },
    });
    await bag.write("/scan", s.ts, {
      header: header("base_link"),
      angle_min: -Math.PI / 2,
      angle_max: Math.PI / 2 - Math.PI / 180,
      angle_increment: Math.PI / 180,
      time_increment: 0,
      scan_time: 0.2,
      range_min: 0.05,
      range_max: 81,
      ranges: Float32Array.from(s.ranges),
      intensities: new Float32Array(0),
    });
    if (i === 10) {
      await bag.write("/points", s.ts, {
        header: header("base_link"),
        height: 1,
        width: points.length,
        fields: ["x", "y", "z", "intensity"].map((name, k) => ({ name, offset: 4 * k, datatype: 7, count: 1 })),
        is_bigendian: false,
        point_step: step,
        row_step: step * points.length,
        data,
        is_dense: true,
      });
    }
  }
  await bag.finish(path.join(out, `bunny-${compression}.mcap`));
}

const [datasets, out] = process.argv.slice(2);
if (!datasets || !out) {
  console.error("usage: node make_bags.mjs DATASETS_DIR OUT_DIR");
  process.exit(2);
}
if (!fs.existsSync(path.join(datasets, "carmen-intel/intel-corrected.log.gz"))) {
  // As the other dataset tests do: without ../shared/datasets beside the checkout there is nothing to convert, and
  // the replay tests skip for want of bags.
  console.log(`datasets not found at ${datasets}; no bags written`);
  process.exit(0);
}
await zstd.isLoaded;
fs.mkdirSync(out, { recursive: true });
for (const compression of ["none", "zstd", "lz4"]) await writeIntel(datasets, out, compression);
await writeExp1(datasets, out, "zstd");
await writeBunny(datasets, out, "lz4");
console.log(`wrote ROS 2 bags to ${out}`);
