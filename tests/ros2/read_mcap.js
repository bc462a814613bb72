#!/usr/bin/env node
// Reads an MCAP file with the ecosystem's own reader, as Foxglove does: @mcap/core's
// McapIndexedReader (footer, summary, chunk indexes, Message Index records; chunk CRCs checked),
// then decodes every message: CDR by its ros2msg schema with @foxglove/rosmsg2-serialization,
// JSON with JSON.parse. Prints one JSON object: messages per topic, schema name and encodings per
// topic, and what the messages hold (cubes in the SceneUpdates, the grid's size, the points).
// Then streams the whole file once more with McapStreamReader (every record, the data section's
// and summary's CRCs checked) and counts its messages.
//
//   node read_mcap.js FILE.mcap
// Exit 0 when every message decoded; any failure throws (exit 1) with the reason.

const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const { parse } = require("@foxglove/rosmsg");
const zstd = require("@foxglove/wasm-zstd");

async function main() {
  const file = process.argv[2];
  if (!file) throw new Error("usage: node read_mcap.js FILE.mcap");
  await zstd.isLoaded;
  const decompressHandlers = { zstd: (data, size) => zstd.decompress(data, Number(size)) };
  const fd = fs.openSync(file, "r");
  const readable = {
    size: async () => BigInt(fs.fstatSync(fd).size),
    read: async (offset, size) => {
      const buf = Buffer.alloc(Number(size));
      const n = fs.readSync(fd, buf, 0, Number(size), Number(offset));
      if (n !== Number(size)) throw new Error(`short read at ${offset}`);
      return buf;
    },
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const decoders = new Map();
  const topics = {};
  for (const channel of reader.channelsById.values()) {
    const schema = reader.schemasById.get(channel.schemaId);
    topics[channel.topic] = { messages: 0, schema: schema.name, schema_encoding: schema.encoding, message_encoding: channel.messageEncoding };
    if (channel.messageEncoding === "cdr") {
      if (schema.encoding !== "ros2msg") throw new Error(`${channel.topic}: cdr without a ros2msg schema`);
      decoders.set(channel.id, new MessageReader(parse(new TextDecoder().decode(schema.data), { ros2: true })));
    } else if (channel.messageEncoding === "json") {
      if (schema.encoding !== "jsonschema") throw new Error(`${channel.topic}: json without a jsonschema schema`);
      JSON.parse(new TextDecoder().decode(schema.data));  // the schema itself must be JSON
      decoders.set(channel.id, { readMessage: (data) => JSON.parse(new TextDecoder().decode(data)) });
    } else {
      throw new Error(`${channel.topic}: message encoding ${channel.messageEncoding} not handled`);
    }
  }
  const out = { topics, messages: 0, cubes: 0, entities: 0, points: 0, poses: 0, foxglove_grid_cells: 0, grid: null, tf: [] };
  for await (const message of reader.readMessages({ validateCrcs: true })) {
    const channel = reader.channelsById.get(message.channelId);
    const msg = decoders.get(message.channelId).readMessage(message.data);
    topics[channel.topic].messages += 1;
    out.messages += 1;
    const type = topics[channel.topic].schema;
    if (type === "foxglove.SceneUpdate") {
      for (const e of msg.entities) {
        out.entities += 1;
        out.cubes += e.cubes.length;
      }
    } else if (type === "foxglove.PointCloud") {
      const bytes = Buffer.from(msg.data, "base64").length;
      if (bytes % msg.point_stride !== 0) throw new Error("point cloud data is not a whole number of points");
      out.points += bytes / msg.point_stride;
    } else if (type === "foxglove.PosesInFrame") {
      out.poses += msg.poses.length;
    } else if (type === "foxglove.Grid") {
      const bytes = Buffer.from(msg.data, "base64").length;
      if (bytes % msg.row_stride !== 0 || msg.row_stride !== msg.column_count * msg.cell_stride) throw new Error("grid data is not whole rows");
      out.foxglove_grid_cells += bytes / msg.cell_stride;
    } else if (type === "nav_msgs/msg/OccupancyGrid") {
      if (msg.data.length !== msg.info.width * msg.info.height) throw new Error("grid data size is not width x height");
      out.grid = { width: msg.info.width, height: msg.info.height, resolution: msg.info.resolution, frame_id: msg.header.frame_id,
                   unknown: msg.data.filter((v) => v === -1).length };
    } else if (type === "tf2_msgs/msg/TFMessage") {
      for (const t of msg.transforms) out.tf.push(`${t.header.frame_id}->${t.child_frame_id}`);
    }
  }
  const stream = new McapStreamReader({ validateCrcs: true, decompressHandlers });
  stream.append(fs.readFileSync(file));
  let streamed = 0;
  for (let record; (record = stream.nextRecord()) !== undefined;) streamed += record.type === "Message" ? 1 : 0;
  if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");
  out.streamed_messages = streamed;
  out.statistics_messages = reader.statistics ? Number(reader.statistics.messageCount) : null;
  console.log(JSON.stringify(out));
}

main().catch((err) => {
  console.error(`read_mcap.js: ${err.message}`);
  process.exit(1);
});
