#!/usr/bin/env node
// Writes the ROS 2 recordings of the hmap::ros tests with the ecosystem's own writers: @mcap/core's
// McapWriter and @foxglove/rosmsg2-serialization's CDR MessageWriter (pinned in package.json),
// from the first real Ouster OS0-64 scans of ../shared/data/balm_os0 (every STEP-th point).
//
// usage: node make_ros2_recordings.js DATA_DIR OUT_DIR [SCANS] [STEP]
//        node make_ros2_recordings.js DATA_DIR --full OUT.mcap [REPEAT]   (all 80 full scans, zstd,
//             /tf + /odom; REPEAT > 1: the 80 scans REPEAT times over, each pass stamped after the
//             last, for a large recording: 10 passes make about 1 GB, written as it goes)
//
// Written to OUT_DIR (stamps = balm_os0/times.txt; P_k = balm_os0/poses.txt):
//   zstd.mcap, lz4.mcap, none.mcap   chunks compressed with zstd / lz4 (frame) / not at all; with a
//        summary (statistics, chunk indexes). Topics: /os_cloud sensor_msgs/msg/PointCloud2 (x y z
//        intensity float32, t uint32 ns = 0..99 ms over the points, frame os_sensor);
//        /tf_static map->odom (translation 1 2 0); /tf odom->os_sensor = P_k at t_k;
//        /odom nav_msgs/msg/Odometry (odom <- os_sensor) = P_k at t_k; /pose
//        geometry_msgs/msg/PoseStamped (odom) = P_k at t_k; /imu sensor_msgs/msg/Imu, 10 messages
//        per scan 10 ms apart from t_k, gyro (0.01 j, -0.02, 0.3), accel (0, 0, 9.81).
//   bigendian.mcap   as none.mcap, but /os_cloud in big-endian CDR (CDR_BE, @foxglove/cdr's
//        CdrWriter field by field: rosmsg2-serialization writes little endian only) with the
//        points big endian too (is_bigendian = true) and its fields in the order z, pad, x, y
//   nosummary.mcap   as zstd.mcap without summary section (the footer's summary start is 0)
//   truncated.mcap   nosummary.mcap cut inside its last cloud's chunk (a recorder killed)
//   badcrc.mcap      none.mcap with one byte of the first cloud's points changed
//   json.mcap        /os_cloud with message encoding "json" (an encoding hmap does not read)
//   r2mcap/          a rosbag2 folder: metadata.yaml + zstd.mcap's copy
//   messages.json    every message of zstd.mcap (topic, type, log time, CDR bytes in base64) for
//                    make_db3.py, which writes the same messages into a rosbag2 .db3 folder
//   manifest.json    what was written: counts per topic, and the messages of truncated.mcap that
//                    @mcap/core's own stream reader reads (the reference for ours)
"use strict";

const fs = require("fs");
const path = require("path");
const { McapWriter, McapStreamReader } = require("@mcap/core");
const { MessageWriter } = require("@foxglove/rosmsg2-serialization");
const { CdrWriter, EncapsulationKind } = require("@foxglove/cdr");
const { parse } = require("@foxglove/rosmsg");
const zstd = require("@foxglove/wasm-zstd");
const lz4 = require("lz4js");

const TIME = "int32 sec\nuint32 nanosec\n";
const HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n";
const sep = (name, text) => `================================================================================\nMSG: ${name}\n${text}`;
const DEFS = {
  "sensor_msgs/msg/PointCloud2":
    "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\n" +
    "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n" +
    sep("std_msgs/Header", HEADER) + sep("builtin_interfaces/Time", TIME) +
    sep("sensor_msgs/PointField", "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\n" +
        "uint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"),
  "tf2_msgs/msg/TFMessage":
    "geometry_msgs/TransformStamped[] transforms\n" +
    sep("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n") +
    sep("std_msgs/Header", HEADER) + sep("builtin_interfaces/Time", TIME) +
    sep("geometry_msgs/Transform", "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n") +
    sep("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n") +
    sep("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"),
  "nav_msgs/msg/Odometry":
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n" +
    sep("std_msgs/Header", HEADER) + sep("builtin_interfaces/Time", TIME) +
    sep("geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose pose\nfloat64[36] covariance\n") +
    sep("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n") +
    sep("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n") +
    sep("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n") +
    sep("geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist twist\nfloat64[36] covariance\n") +
    sep("geometry_msgs/Twist", "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n") +
    sep("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
  "geometry_msgs/msg/PoseStamped":
    "std_msgs/Header header\ngeometry_msgs/Pose pose\n" +
    sep("std_msgs/Header", HEADER) + sep("builtin_interfaces/Time", TIME) +
    sep("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n") +
    sep("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n") +
    sep("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"),
  "sensor_msgs/msg/Imu":
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n" +
    "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n" +
    "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n" +
    sep("std_msgs/Header", HEADER) + sep("builtin_interfaces/Time", TIME) +
    sep("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n") +
    sep("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
};
const WRITERS = Object.fromEntries(Object.entries(DEFS).map(([type, text]) => [type, new MessageWriter(parse(text, { ros2: true }))]));

function readScans(dataDir, scans, step) {
  const dir = path.join(dataDir, "balm_os0");
  const times = fs.readFileSync(path.join(dir, "times.txt"), "utf8").trim().split(/\s+/).map(Number);
  const poses = fs.readFileSync(path.join(dir, "poses.txt"), "utf8").trim().split("\n").map((l) => l.trim().split(/\s+/).map(Number));
  const out = [];
  for (let k = 0; k < scans; ++k) {
    const bin = fs.readFileSync(path.join(dir, "velodyne", String(k).padStart(6, "0") + ".bin"));
    const all = new Float32Array(bin.buffer, bin.byteOffset, bin.length / 4);
    const pts = [];
    for (let i = 0; i < all.length / 4; i += step) pts.push([all[4 * i], all[4 * i + 1], all[4 * i + 2], all[4 * i + 3]]);
    out.push({ t: times[k], P: poses[k], points: pts });
  }
  return out;
}

// Shepperd's method on the 3x4 row-major pose; the rotation is orthonormal to ~1e-6.
function quaternion(P) {
  const r = [[P[0], P[1], P[2]], [P[4], P[5], P[6]], [P[8], P[9], P[10]]];
  const w = Math.sqrt(Math.max(0, 1 + r[0][0] + r[1][1] + r[2][2])) / 2;
  let x = Math.sqrt(Math.max(0, 1 + r[0][0] - r[1][1] - r[2][2])) / 2;
  let y = Math.sqrt(Math.max(0, 1 - r[0][0] + r[1][1] - r[2][2])) / 2;
  let z = Math.sqrt(Math.max(0, 1 - r[0][0] - r[1][1] + r[2][2])) / 2;
  x = Math.sign(r[2][1] - r[1][2]) * x || x;
  y = Math.sign(r[0][2] - r[2][0]) * y || y;
  z = Math.sign(r[1][0] - r[0][1]) * z || z;
  return { x, y, z, w };
}

const stampOf = (t) => ({ sec: Math.floor(t), nanosec: Math.round((t - Math.floor(t)) * 1e9) % 1000000000 });
const nsOf = (t) => BigInt(Math.floor(t)) * 1000000000n + BigInt(Math.round((t - Math.floor(t)) * 1e9) % 1000000000);

function cloudMessage(scan) {
  const n = scan.points.length;
  const step = 20;
  const data = new Uint8Array(n * step);
  const view = new DataView(data.buffer);
  scan.points.forEach((p, i) => {
    for (let a = 0; a < 4; ++a) view.setFloat32(i * step + 4 * a, p[a], true);
    view.setUint32(i * step + 16, Math.floor((i * 100000000) / n), true);  // ns: 0 .. 99 ms over the cloud
  });
  const field = (name, offset, datatype) => ({ name, offset, datatype, count: 1 });
  return {
    header: { stamp: stampOf(scan.t), frame_id: "os_sensor" },
    height: 1, width: n,
    fields: [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 12, 7), field("t", 16, 6)],
    is_bigendian: false, point_step: step, row_step: n * step, data, is_dense: true,
  };
}

/// Every message of the recording, in log-time order: [topic, type, time [s], message object].
function messagesOf(scans, full) {
  const out = [];
  const tfs = (t, parent, child, P, tr) => ({
    transforms: [{ header: { stamp: stampOf(t), frame_id: parent }, child_frame_id: child,
                   transform: { translation: tr ?? { x: P[3], y: P[7], z: P[11] }, rotation: P ? quaternion(P) : { x: 0, y: 0, z: 0, w: 1 } } }],
  });
  out.push(["/tf_static", "tf2_msgs/msg/TFMessage", scans[0].t - 0.5, tfs(scans[0].t - 0.5, "map", "odom", null, { x: 1, y: 2, z: 0 })]);
  scans.forEach((s) => {
    const pose = { position: { x: s.P[3], y: s.P[7], z: s.P[11] }, orientation: quaternion(s.P) };
    out.push(["/tf", "tf2_msgs/msg/TFMessage", s.t, tfs(s.t, "odom", "os_sensor", s.P)]);
    out.push(["/odom", "nav_msgs/msg/Odometry", s.t, {
      header: { stamp: stampOf(s.t), frame_id: "odom" }, child_frame_id: "os_sensor",
      pose: { pose, covariance: new Array(36).fill(0) },
      twist: { twist: { linear: { x: 0, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } }, covariance: new Array(36).fill(0) },
    }]);
    if (!full) {
      out.push(["/pose", "geometry_msgs/msg/PoseStamped", s.t, { header: { stamp: stampOf(s.t), frame_id: "odom" }, pose }]);
      for (let j = 0; j < 10; ++j) {
        const t = s.t + 0.01 * j;
        out.push(["/imu", "sensor_msgs/msg/Imu", t, {
          header: { stamp: stampOf(t), frame_id: "imu" }, orientation: { x: 0, y: 0, z: 0, w: 1 },
          orientation_covariance: [-1, 0, 0, 0, 0, 0, 0, 0, 0],
          angular_velocity: { x: 0.01 * j, y: -0.02, z: 0.3 }, angular_velocity_covariance: new Array(9).fill(0),
          linear_acceleration: { x: 0, y: 0, z: 9.81 }, linear_acceleration_covariance: new Array(9).fill(0),
        }]);
      }
    }
    out.push(["/os_cloud", "sensor_msgs/msg/PointCloud2", s.t + 0.001, cloudMessage(s)]);
  });
  return out;
}

/// Writes as it goes (the --full recording is too large to hold twice).
class StreamWritable {
  constructor(file) { this.fd = fs.openSync(file, "w"); this.size = 0n; }
  position() { return this.size; }
  async write(buffer) { fs.writeSync(this.fd, buffer); this.size += BigInt(buffer.byteLength); }
  close() { fs.closeSync(this.fd); }
}

class FileWritable {
  constructor() { this.parts = []; this.size = 0n; }
  position() { return this.size; }
  async write(buffer) { this.parts.push(Buffer.from(buffer)); this.size += BigInt(buffer.byteLength); }
  bytes() { return Buffer.concat(this.parts); }
}

/// A PointCloud2 in big-endian CDR with big-endian points laid out z, 4 pad bytes, x, y, t.
function bigEndianCloud(msg, scan) {
  const n = scan.points.length;
  const step = 20;
  const data = new Uint8Array(n * step);
  const view = new DataView(data.buffer);
  scan.points.forEach((p, i) => {
    view.setFloat32(i * step, p[2], false);
    view.setFloat32(i * step + 8, p[0], false);
    view.setFloat32(i * step + 12, p[1], false);
    view.setUint32(i * step + 16, Math.floor((i * 100000000) / n), false);
  });
  const w = new CdrWriter({ kind: EncapsulationKind.CDR_BE });
  w.int32(msg.header.stamp.sec).uint32(msg.header.stamp.nanosec).string(msg.header.frame_id);
  w.uint32(1).uint32(n);
  const fields = [["z", 0, 7], ["x", 8, 7], ["y", 12, 7], ["t", 16, 6]];
  w.sequenceLength(fields.length);
  for (const [name, offset, datatype] of fields) w.string(name).uint32(offset).uint8(datatype).uint32(1);
  w.uint8(1).uint32(step).uint32(n * step).uint8Array(data, true).uint8(1);
  return w.data;
}

async function writeMcap(messages, { compression, summary, encoding, bigEndianClouds, writable = new FileWritable() }) {
  const compressChunk =
    compression === "zstd" ? (d) => ({ compression: "zstd", compressedData: zstd.compress(d, 3) })
    : compression === "lz4" ? (d) => ({ compression: "lz4", compressedData: lz4.compress(d) })
    : undefined;
  const writer = new McapWriter({
    writable, chunkSize: 64 * 1024, compressChunk,
    useStatistics: summary, useChunkIndex: summary, useMessageIndex: summary, useSummaryOffsets: summary,
    repeatSchemas: summary, repeatChannels: summary, useAttachmentIndex: summary, useMetadataIndex: summary,
  });
  await writer.start({ profile: "ros2", library: "hmap tests (@mcap/core)" });
  const channels = {};
  const counts = {};
  let sequence = 0;
  for (const [topic, type, t, msg] of messages) {
    if (!(topic in channels)) {
      const schemaId = await writer.registerSchema({ name: type, encoding: "ros2msg", data: Buffer.from(DEFS[type]) });
      channels[topic] = await writer.registerChannel({ topic, schemaId, messageEncoding: encoding ?? "cdr", metadata: new Map() });
    }
    counts[topic] = (counts[topic] ?? 0) + 1;
    const ns = nsOf(t);
    const data = bigEndianClouds && topic === "/os_cloud" ? bigEndianCloud(msg, bigEndianClouds.shift()) : WRITERS[type].writeMessage(msg);
    await writer.addMessage({ channelId: channels[topic], sequence: sequence++, logTime: ns, publishTime: ns, data });
  }
  await writer.end();
  return { bytes: writable.bytes ? writable.bytes() : undefined, counts };
}

/// The messages @mcap/core's own stream reader reads from `bytes` (it stops at an incomplete record).
function countWithStreamReader(bytes) {
  const reader = new McapStreamReader({ validateCrcs: true, decompressHandlers: { zstd: (d, n) => zstd.decompress(d, Number(n)) } });
  reader.append(bytes);
  const channels = {};
  const counts = {};
  for (let r; (r = reader.nextRecord()) !== undefined;) {
    if (r.type === "Channel") channels[r.id] = r.topic;
    if (r.type === "Message") counts[channels[r.channelId]] = (counts[channels[r.channelId]] ?? 0) + 1;
  }
  return counts;
}

async function main() {
  const [dataDir, outArg, third, fourth] = process.argv.slice(2);
  await zstd.isLoaded;
  if (outArg === "--full") {
    const scans = readScans(dataDir, 80, 1);
    const repeat = Number(fourth ?? 1);
    if (!(Number.isInteger(repeat) && repeat >= 1 && repeat <= 100)) throw new Error(`REPEAT ${fourth}: give 1..100`);
    const period = scans[scans.length - 1].t - scans[0].t + 0.5;
    // Pass r: the same scans and poses, every stamp r periods later. Messages are made pass by pass.
    function* passes() {
      for (let r = 0; r < repeat; ++r) {
        const messages = messagesOf(scans.map((s) => ({ ...s, t: s.t + r * period })), true);
        yield* (r === 0 ? messages : messages.filter(([topic]) => topic !== "/tf_static"));
      }
    }
    const writable = new StreamWritable(third);
    const { counts } = await writeMcap(passes(), { compression: "zstd", summary: true, writable });
    writable.close();
    console.log(`${third}: ${writable.size} bytes`, counts);
    return;
  }
  const out = outArg;
  const scans = readScans(dataDir, Number(third ?? 3), Number(fourth ?? 10));
  fs.mkdirSync(out, { recursive: true });
  const messages = messagesOf(scans, false);
  const manifest = { scans: scans.length, points: scans.map((s) => s.points.length), files: {} };
  for (const [name, options] of [
    ["zstd.mcap", { compression: "zstd", summary: true }],
    ["lz4.mcap", { compression: "lz4", summary: true }],
    ["none.mcap", { compression: "none", summary: true }],
    ["nosummary.mcap", { compression: "zstd", summary: false }],
    ["json.mcap", { compression: "none", summary: true, encoding: "json" }],
    ["bigendian.mcap", { compression: "none", summary: true, bigEndianClouds: [...scans] }],
  ]) {
    const { bytes, counts } = await writeMcap(messages, options);
    fs.writeFileSync(path.join(out, name), bytes);
    manifest.files[name] = counts;
    if (name === "nosummary.mcap") {
      // Cut inside the last cloud's chunk: the last cloud is the file's last message, its chunk
      // the last before the data end record; cutting 1000 bytes before that record cuts it.
      const cut = bytes.subarray(0, bytes.length - 8 - 29 - 13 - 1000);
      fs.writeFileSync(path.join(out, "truncated.mcap"), cut);
      manifest.files["truncated.mcap"] = countWithStreamReader(cut);
    }
    if (name === "none.mcap") {
      const bad = Buffer.from(bytes);
      // A byte inside the first cloud's point data (the first cloud message lies well past 2 kB).
      const at = bad.indexOf(Buffer.from("os_sensor")) + 4000;
      bad[at] ^= 0x5a;
      fs.writeFileSync(path.join(out, "badcrc.mcap"), bad);
    }
  }
  fs.mkdirSync(path.join(out, "r2mcap"), { recursive: true });
  fs.copyFileSync(path.join(out, "zstd.mcap"), path.join(out, "r2mcap", "r2mcap_0.mcap"));
  const topicLines = Object.entries(manifest.files["zstd.mcap"]).map(([topic, n]) =>
    `    - topic_metadata:\n        name: ${topic}\n        type: ${messages.find((m) => m[0] === topic)[1]}\n        serialization_format: cdr\n      message_count: ${n}\n`).join("");
  fs.writeFileSync(path.join(out, "r2mcap", "metadata.yaml"),
    `rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  relative_file_paths:\n    - r2mcap_0.mcap\n` +
    `  message_count: ${messages.length}\n  topics_with_message_count:\n${topicLines}  compression_format: ""\n  compression_mode: ""\n`);
  fs.writeFileSync(path.join(out, "messages.json"), JSON.stringify(messages.map(([topic, type, t, msg]) =>
    ({ topic, type, time_ns: nsOf(t).toString(), cdr: Buffer.from(WRITERS[type].writeMessage(msg)).toString("base64") }))));
  fs.writeFileSync(path.join(out, "manifest.json"), JSON.stringify(manifest, null, 1));
}

main().catch((e) => {
  console.error(e);
  process.exit(1);
});
