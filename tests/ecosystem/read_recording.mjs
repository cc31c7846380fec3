// Reads an `occgeo record` file with the MCAP ecosystem's own libraries: @mcap/core's indexed reader (through the
// summary, chunk indexes and message indexes) and its stream reader (front to back, every CRC checked), and decodes
// every message with protobufjs from the FileDescriptorSet embedded as its schema, as Foxglove does.
//   node read_recording.mjs FILE.mcap
// Prints one JSON object: per topic the schema, encodings and message count; what the decoded messages hold.
import fs from "node:fs";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import * as zstd from "@foxglove/wasm-zstd";
import lz4 from "lz4js";
import protobuf from "protobufjs";
import "protobufjs/ext/descriptor.js";

const file = process.argv[2];
await zstd.isLoaded;
const decompressHandlers = {
  zstd: (buffer, size) => zstd.decompress(buffer, Number(size)),
  lz4: (buffer, size) => Uint8Array.from(lz4.decompress(buffer, Number(size))),
};
const bytes = fs.readFileSync(file);

// One protobufjs type per schema, built from the schema's own FileDescriptorSet.
const types = new Map();
function typeOf(schema) {
  if (!types.has(schema.id)) {
    if (schema.encoding !== "protobuf") throw new Error(`schema ${schema.name} is encoded as ${schema.encoding}`);
    const root = protobuf.Root.fromDescriptor(schema.data);
    types.set(schema.id, root.lookupType(schema.name));
  }
  return types.get(schema.id);
}

const out = {
  profile: "",
  indexed_messages: 0,
  streamed_messages: 0,
  statistics_messages: 0,
  chunk_indexes: 0,
  topics: {},
  robot_models: [],
  laser_scans: 0,
  laser_beams_min: null,
  placements_with_pose: 0,
  placements_with_changed_cells: 0,
  odometry: 0,
  motion_commands: 0,
  max_seq_by_topic: {},
};

// Indexed: what a viewer that seeks does.
const readable = {
  size: async () => BigInt(bytes.length),
  read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
};
const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
out.profile = indexed.header.profile;
out.statistics_messages = Number(indexed.statistics?.messageCount ?? -1n);
out.chunk_indexes = indexed.chunkIndexes.length;
for await (const message of indexed.readMessages()) {
  const channel = indexed.channelsById.get(message.channelId);
  const schema = indexed.schemasById.get(channel.schemaId);
  const decoded = typeOf(schema).toObject(typeOf(schema).decode(message.data), { longs: Number, defaults: true });
  out.indexed_messages += 1;
  const topic = (out.topics[channel.topic] ??= {
    schema: schema.name,
    schema_encoding: schema.encoding,
    message_encoding: channel.messageEncoding,
    robot_id: channel.metadata.get("robot_id") ?? "",
    count: 0,
  });
  topic.count += 1;
  if (decoded.seq !== undefined) {
    out.max_seq_by_topic[channel.topic] = Math.max(out.max_seq_by_topic[channel.topic] ?? 0, decoded.seq);
  }
  switch (schema.name) {
    case "occgeo.v1.RobotSpec":
      out.robot_models.push(decoded.model);
      break;
    case "occgeo.v1.LaserScan":
      out.laser_scans += 1;
      out.laser_beams_min = Math.min(out.laser_beams_min ?? Infinity, decoded.ranges.length);
      break;
    case "occgeo.v1.WatchEvent":
      if (decoded.pose && Number.isFinite(decoded.pose.x)) out.placements_with_pose += 1;
      const cells = decoded.changedCells ?? decoded.changed_cells;
      if (cells && cells.max.ix >= cells.min.ix) {
        out.placements_with_changed_cells += 1;
      }
      break;
    case "occgeo.v1.Odometry":
      out.odometry += 1;
      break;
    case "occgeo.v1.MotionCommand":
      out.motion_commands += 1;
      break;
  }
}

// Streamed, CRCs validated: what a tool that reads the file front to back does.
const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
stream.append(bytes);
for (let record; (record = stream.nextRecord()); ) {
  if (record.type === "Message") out.streamed_messages += 1;
}
if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");

console.log(JSON.stringify(out));
