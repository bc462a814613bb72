#!/usr/bin/env node
// Reads an MCAP file with the ecosystem's own reader, as Foxglove does: @mcap/core's
// McapIndexedReader (footer, summary, chunk indexes, Message Index records; chunk CRCs checked),
// then decodes every message: CDR by its ros2msg schema with @foxglove/rosmsg2-serialization,
// JSON with JSON.parse. Prints one JSON object: messages per topic, schema name and encodings per
// topic, and what the messages hold (cubes in the SceneUpdates, the grid's size, the points).
// Then streams the whole file once more with McapStreamReader (every record, the data section's
// and summary's CRCs checked) and counts its messages.
// Time: every stamp a message carries (ROS headers, foxglove timestamps) must be its log time and
// publish time; the Statistics' message count, start and end times and per-channel counts must be
// those of the messages read; each Chunk record's and Chunk Index's start and end times those of the
// chunk's messages, and each Message Index the chunk's messages of its channel, by log time. The
// log times are printed per topic (ns, as decimal strings: they exceed 2^53).
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
  const out = { topics, messages: 0, cubes: 0, entities: 0, points: 0, poses: 0, foxglove_grid_cells: 0, grid: null, tf: [],
                log_times: {}, stamps_checked: 0 };
  const rosNs = (t) => BigInt(t.sec) * 1000000000n + BigInt(t.nanosec);
  const jsonNs = (t) => BigInt(t.sec) * 1000000000n + BigInt(t.nsec);
  let first = null, last = null;
  const counts = new Map();  // channel id -> messages
  for await (const message of reader.readMessages({ validateCrcs: true })) {
    const channel = reader.channelsById.get(message.channelId);
    const msg = decoders.get(message.channelId).readMessage(message.data);
    topics[channel.topic].messages += 1;
    out.messages += 1;
    const t = message.logTime;
    (out.log_times[channel.topic] ??= []).push(t.toString());
    if (message.publishTime !== t) throw new Error(`${channel.topic}: publish time ${message.publishTime} is not the log time ${t}`);
    first = first === null || t < first ? t : first;
    last = last === null || t > last ? t : last;
    counts.set(message.channelId, (counts.get(message.channelId) ?? 0) + 1);
    const stamps = [];  // the stamps the message carries, each to equal its log time
    if (msg.header) stamps.push(rosNs(msg.header.stamp));
    if (msg.transforms) for (const tr of msg.transforms) stamps.push(rosNs(tr.header.stamp));
    if (msg.timestamp) stamps.push(jsonNs(msg.timestamp));
    if (msg.entities) for (const e of msg.entities) stamps.push(jsonNs(e.timestamp));
    for (const stamp of stamps) {
      if (stamp !== t) throw new Error(`${channel.topic}: a message stamped ${stamp} is logged at ${t}`);
      out.stamps_checked += 1;
    }
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
  // The summary's statistics against the messages read.
  const st = reader.statistics;
  if (!st) throw new Error("no statistics record in the summary");
  if (Number(st.messageCount) !== out.messages) throw new Error(`statistics: ${st.messageCount} messages, ${out.messages} read`);
  if (out.messages > 0 && (st.messageStartTime !== first || st.messageEndTime !== last)) {
    throw new Error(`statistics: messages from ${st.messageStartTime} to ${st.messageEndTime}, read from ${first} to ${last}`);
  }
  for (const [id, n] of counts) {
    if (Number(st.channelMessageCounts.get(id) ?? 0n) !== n) throw new Error(`statistics: channel ${id} counts ${st.channelMessageCounts.get(id)}, ${n} read`);
  }
  for (const [id, n] of st.channelMessageCounts) {
    if (Number(n) !== (counts.get(id) ?? 0)) throw new Error(`statistics: channel ${id} counts ${n}, ${counts.get(id) ?? 0} read`);
  }
  out.statistics = { messages: Number(st.messageCount), start: st.messageStartTime.toString(), end: st.messageEndTime.toString() };

  // Streamed: each chunk with the messages inside it and the Message Index records after it.
  const stream = new McapStreamReader({ validateCrcs: true, decompressHandlers, includeChunks: true });
  stream.append(fs.readFileSync(file));
  let streamed = 0;
  const chunks = [];
  let chunk = null;  // the chunk whose messages are being read
  for (let record; (record = stream.nextRecord()) !== undefined;) {
    if (record.type === "Chunk") {
      chunk = { start: record.messageStartTime, end: record.messageEndTime, times: new Map(), indexed: new Map() };
      chunks.push(chunk);
    } else if (record.type === "Message") {
      streamed += 1;
      if (chunk) {
        if (!chunk.times.has(record.channelId)) chunk.times.set(record.channelId, []);
        chunk.times.get(record.channelId).push(record.logTime);
      }
    } else if (record.type === "MessageIndex") {
      const last = chunks[chunks.length - 1];
      last.indexed.set(record.channelId, record.records.map(([time]) => time));
      chunk = null;  // the chunk's records are over
    }
  }
  if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");
  const byOffset = [...reader.chunkIndexes].sort((a, b) => (a.chunkStartOffset < b.chunkStartOffset ? -1 : 1));
  if (byOffset.length !== chunks.length) throw new Error(`${byOffset.length} chunk indexes for ${chunks.length} chunks`);
  chunks.forEach((c, k) => {
    const all = [...c.times.values()].flat();
    const lo = all.reduce((a, b) => (b < a ? b : a)), hi = all.reduce((a, b) => (b > a ? b : a));
    if (c.start !== lo || c.end !== hi) throw new Error(`chunk ${k}: record says ${c.start} to ${c.end}, its messages ${lo} to ${hi}`);
    if (byOffset[k].messageStartTime !== lo || byOffset[k].messageEndTime !== hi) {
      throw new Error(`chunk ${k}: index says ${byOffset[k].messageStartTime} to ${byOffset[k].messageEndTime}, its messages ${lo} to ${hi}`);
    }
    for (const [id, times] of c.times) {
      const indexed = c.indexed.get(id);
      if (!indexed) throw new Error(`chunk ${k}: no message index for channel ${id}`);
      const sorted = [...times].sort((a, b) => (a < b ? -1 : a > b ? 1 : 0));
      if (indexed.length !== sorted.length || indexed.some((t, i) => t !== sorted[i])) {
        throw new Error(`chunk ${k}: the message index of channel ${id} is not its messages' log times in order`);
      }
    }
  });
  out.chunks_checked = chunks.length;
  out.streamed_messages = streamed;
  out.statistics_messages = Number(st.messageCount);
  console.log(JSON.stringify(out));
}

main().catch((err) => {
  console.error(`read_mcap.js: ${err.message}`);
  process.exit(1);
});
