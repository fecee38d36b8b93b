// Writes a ROS 2 recording of a 7-Scenes layout sequence (mobmap simulate's) with the
// npm registry's MCAP writer (@mcap/core) and CDR serialiser
// (@foxglove/rosmsg2-serialization), so that mobmap's own readers are checked against
// implementations other than their own.
//
//   node write_bag.mjs --seq DIR --out FILE.mcap [options]
//   node write_bag.mjs --seq DIR --feed FILE.jsonl [options]   (messages for make_db3.py)
//
// Options:
//   --depth 16UC1|32FC1|compressed16|compressed32   how depth is stored (16UC1)
//   --layout camera|base   camera: /tf gives map -> the optical frame directly;
//                          base: map -> odom (constant, on /tf), odom -> base_link
//                          (two samples 5 ms either side of each image, interpolating
//                          to its pose), static base_link -> camera_link -> optical (camera)
//   --world map|odom       the root frame (base layout with odom: no map frame)
//   --chunks none|plain|lz4|zstd   MCAP chunking and compression (zstd)
//   --summary yes|no       MCAP summary section (yes)
//   --colour               also a colour image topic and its camera_info
//   --second-camera        the depth and camera_info again, under /camera2
//   --tilt DEG             the world frame turned DEG about its x axis (camera layout): its
//                          -z is no longer down
//   --imu                  an Imu on the camera (/camera/imu, the optical frame): still
//                          readings at each image, moving ones (3 m/s^2 more) between
//   --distortion K1,K2,P1,P2,K3  plumb_bob coefficients in the camera_info (zeros)
//   --frames N             only the first N frames
//   --repeat K             the frames K times over, one after another (a long recording)
//   --crop WxH             only the top-left W x H pixels of each image (small fuzzing seeds)
//   --pad-mib M            after each image, a message of M MiB of zeros on /padding (a
//                          type mobmap does not read): chunks that compress to little and
//                          expand to M MiB each
//   --fault bigendian|step|size|cycle|no-static|two-parents
//                          a recording that is wrong in one way: big-endian depth, a step
//                          shorter than a row, a camera_info of another size, a TF cycle
//                          (base layout, odom world), no /tf_static (base layout), a frame
//                          with two parents
import fs from "node:fs";
import path from "node:path";
import zlib from "node:zlib";
import { createRequire } from "node:module";
import { McapWriter } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";

const require = createRequire(import.meta.url);
const lz4 = require("lz4js");
const zstd = require("@foxglove/wasm-zstd");

// ---- arguments ------------------------------------------------------------------------
const args = { depth: "16UC1", layout: "camera", world: "map", chunks: "zstd", summary: "yes", colour: false, fault: "" };
for (let i = 2; i < process.argv.length; ++i) {
  const key = process.argv[i].replace(/^--/, "");
  if (key === "colour" || key === "second-camera" || key === "imu") args[key] = true;
  else args[key] = process.argv[++i];
}
if (!args.seq || (!args.out && !args.feed)) {
  console.error("usage: node write_bag.mjs --seq DIR (--out FILE.mcap | --feed FILE.jsonl) [options]");
  process.exit(2);
}

// ---- a 16-bit greyscale PNG, decoded (zlib + the five row filters) ----------------------
function readPng16(file) {
  const buf = fs.readFileSync(file);
  let at = 8, width = 0, height = 0;
  const idat = [];
  while (at < buf.length) {
    const len = buf.readUInt32BE(at);
    const type = buf.toString("latin1", at + 4, at + 8);
    const body = buf.subarray(at + 8, at + 8 + len);
    if (type === "IHDR") {
      width = body.readUInt32BE(0);
      height = body.readUInt32BE(4);
      if (body[8] !== 16 || body[9] !== 0 || body[12] !== 0) throw new Error(`${file}: not a 16-bit greyscale PNG`);
    } else if (type === "IDAT") idat.push(body);
    at += 12 + len;
  }
  const raw = zlib.inflateSync(Buffer.concat(idat));
  const bpp = 2, stride = width * 2;
  const out = new Uint16Array(width * height);
  let prev = Buffer.alloc(stride);
  for (let y = 0; y < height; ++y) {
    const filter = raw[y * (stride + 1)];
    const line = Buffer.from(raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1)));
    for (let x = 0; x < stride; ++x) {
      const a = x >= bpp ? line[x - bpp] : 0, b = prev[x], c = x >= bpp ? prev[x - bpp] : 0;
      let p = 0;
      if (filter === 1) p = a;
      else if (filter === 2) p = b;
      else if (filter === 3) p = (a + b) >> 1;
      else if (filter === 4) {
        const q = a + b - c, pa = Math.abs(q - a), pb = Math.abs(q - b), pc = Math.abs(q - c);
        p = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      line[x] = (line[x] + p) & 0xff;
    }
    for (let x = 0; x < width; ++x) out[y * width + x] = (line[2 * x] << 8) | line[2 * x + 1];
    prev = line;
  }
  return { width, height, pixels: out };
}

function crop(img) {
  if (!args.crop) return img;
  const [w, h] = args.crop.split("x").map(Number);
  const pixels = new Uint16Array(w * h);
  for (let y = 0; y < h; ++y) for (let x = 0; x < w; ++x) pixels[y * w + x] = img.pixels[y * img.width + x];
  return { width: w, height: h, pixels };
}

// ---- rigid transforms as { R: 3x3 row-major array, t: [x, y, z] } ------------------------
const mul = (A, B) => ({
  R: [0, 1, 2].flatMap((i) => [0, 1, 2].map((j) => A.R[3 * i] * B.R[j] + A.R[3 * i + 1] * B.R[3 + j] + A.R[3 * i + 2] * B.R[6 + j])),
  t: [0, 1, 2].map((i) => A.R[3 * i] * B.t[0] + A.R[3 * i + 1] * B.t[1] + A.R[3 * i + 2] * B.t[2] + A.t[i]),
});
const inv = (A) => {
  const R = [A.R[0], A.R[3], A.R[6], A.R[1], A.R[4], A.R[7], A.R[2], A.R[5], A.R[8]];
  return { R, t: [0, 1, 2].map((i) => -(R[3 * i] * A.t[0] + R[3 * i + 1] * A.t[1] + R[3 * i + 2] * A.t[2])) };
};
function quatOf(R) {  // Shepperd's method
  const [m00, m01, m02, m10, m11, m12, m20, m21, m22] = R;
  const tr = m00 + m11 + m22;
  let x, y, z, w;
  if (tr > 0) {
    const s = Math.sqrt(tr + 1) * 2; w = s / 4; x = (m21 - m12) / s; y = (m02 - m20) / s; z = (m10 - m01) / s;
  } else if (m00 > m11 && m00 > m22) {
    const s = Math.sqrt(1 + m00 - m11 - m22) * 2; w = (m21 - m12) / s; x = s / 4; y = (m01 + m10) / s; z = (m02 + m20) / s;
  } else if (m11 > m22) {
    const s = Math.sqrt(1 + m11 - m00 - m22) * 2; w = (m02 - m20) / s; x = (m01 + m10) / s; y = s / 4; z = (m12 + m21) / s;
  } else {
    const s = Math.sqrt(1 + m22 - m00 - m11) * 2; w = (m10 - m01) / s; x = (m02 + m20) / s; y = (m12 + m21) / s; z = s / 4;
  }
  const n = Math.hypot(x, y, z, w);
  return { x: x / n, y: y / n, z: z / n, w: w / n };
}
function rotOf(axis, angle) {  // Rodrigues
  const n = Math.hypot(...axis), [x, y, z] = axis.map((v) => v / n), c = Math.cos(angle), s = Math.sin(angle), C = 1 - c;
  return [c + x * x * C, x * y * C - z * s, x * z * C + y * s, y * x * C + z * s, c + y * y * C, y * z * C - x * s,
          z * x * C - y * s, z * y * C + x * s, c + z * z * C];
}
const pose = (R, t) => ({ R, t });

// ---- the sequence -----------------------------------------------------------------------
const seq = args.seq;
let numbers = fs.readdirSync(seq).filter((f) => /^frame-\d+\.depth\.png$/.test(f)).map((f) => parseInt(f.slice(6, 12), 10)).sort((a, b) => a - b);
if (args.frames) numbers = numbers.slice(0, parseInt(args.frames, 10));
if (args.repeat) numbers = Array.from({ length: parseInt(args.repeat, 10) }, () => numbers).flat();
const name = (n, ext) => path.join(seq, `frame-${String(n).padStart(6, "0")}.${ext}`);
const K = fs.readFileSync(path.join(seq, "camera-intrinsics.txt"), "utf8").trim().split(/\s+/).map(Number);
const readPose = (n) => {
  const v = fs.readFileSync(name(n, "pose.txt"), "utf8").trim().split(/\s+/).map(Number);
  return pose([v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]], [v[3], v[7], v[11]]);
};
const t0 = 1700000000n * 1000000000n;
const stampOf = (i) => t0 + BigInt(Math.round((i * 1e9) / 30));

// ---- message definitions (ROS 2) ----------------------------------------------------------
const SEP = "\n================================================================================\nMSG: ";
const TIME = "builtin_interfaces/Time\nint32 sec\nuint32 nanosec";
const HEADER = "std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id";
const defs = {
  "sensor_msgs/msg/Image": "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data" + SEP + HEADER + SEP + TIME,
  "sensor_msgs/msg/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data" + SEP + HEADER + SEP + TIME,
  "sensor_msgs/msg/CameraInfo": "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi" +
    SEP + HEADER + SEP + TIME + SEP + "sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify",
  "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms" + SEP + "geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform" +
    SEP + HEADER + SEP + TIME + SEP + "geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation" +
    SEP + "geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z" + SEP + "geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w",
  "sensor_msgs/msg/Imu": "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance" +
    SEP + HEADER + SEP + TIME + SEP + "geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w" + SEP + "geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z",
};
const writers = Object.fromEntries(Object.entries(defs).map(([k, v]) => [k, new MessageWriter(parse(v, { ros2: true }))]));
const timeOf = (ns) => ({ sec: Number(ns / 1000000000n), nanosec: Number(ns % 1000000000n) });
const header = (ns, frame) => ({ stamp: timeOf(ns), frame_id: frame });
const tfOf = (ns, parent, child, T) => {
  const q = quatOf(T.R);
  return { header: header(ns, parent), child_frame_id: child, transform: { translation: { x: T.t[0], y: T.t[1], z: T.t[2] }, rotation: q } };
};

// ---- the messages, in time order ------------------------------------------------------------
const messages = [];  // { topic, type, t (BigInt ns), data }
const add = (topic, type, t, msg) => messages.push({ topic, type, t, data: writers[type].writeMessage(msg) });
const OPTICAL = "camera_depth_optical_frame";
const distortion = args.distortion ? args.distortion.split(",").map(Number) : [0, 0, 0, 0, 0];
const T_map_odom = pose(rotOf([0, 0, 1], 0.5), [3.0, -2.0, 0.0]);
const T_base_link = pose(rotOf([0, 1, 0], 0.3), [0.25, 0.05, 0.9]);       // base_link -> camera_link
const T_link_optical = pose([0, 0, 1, -1, 0, 0, 0, -1, 0], [0.0, 0.02, 0.0]);  // camera_link -> optical (z ahead, x right)
const T_base_optical = mul(T_base_link, T_link_optical);
const root = args.world;

if (args.layout === "base" && args.fault !== "no-static") {
  const statics = [tfOf(t0, "base_link", "camera_link", T_base_link), tfOf(t0, "camera_link", OPTICAL, T_link_optical)];
  if (args.fault === "cycle") statics.push(tfOf(t0, OPTICAL, "odom", T_map_odom));
  if (args.fault === "two-parents") statics.push(tfOf(t0, "odom", "camera_link", T_map_odom));
  add("/tf_static", "tf2_msgs/msg/TFMessage", t0, { transforms: statics });
}
numbers.forEach((n, i) => {
  const t = stampOf(i);
  const T_world_camera = readPose(n);
  if (args.layout === "camera") {
    const T_root_camera = args.tilt ? mul(pose(rotOf([1, 0, 0], (Number(args.tilt) * Math.PI) / 180), [0, 0, 0]), T_world_camera) : T_world_camera;
    add("/tf", "tf2_msgs/msg/TFMessage", t, { transforms: [tfOf(t, root, OPTICAL, T_root_camera)] });
  } else {
    // odom -> base_link, sampled 5 ms before and after the image: turned and moved by
    // equal and opposite amounts about the true pose, so interpolating at the image's
    // stamp gives it back.
    const T_odom_base = mul(root === "map" ? inv(T_map_odom) : pose([1, 0, 0, 0, 1, 0, 0, 0, 1], [0, 0, 0]), mul(T_world_camera, inv(T_base_optical)));
    const angle = 0.01 * ((i % 5) + 1), shift = [0.003 * (i % 3), -0.002, 0.001];
    for (const sign of [-1, 1]) {
      const ts = t + BigInt(sign * 5000000);
      const T = pose(mul(T_odom_base, pose(rotOf([0.3, 0.2, 1], sign * angle), [0, 0, 0])).R, T_odom_base.t.map((v, k) => v + sign * shift[k]));
      const tf = [tfOf(ts, "odom", "base_link", T)];
      if (root === "map") tf.push(tfOf(ts, "map", "odom", T_map_odom));
      add("/tf", "tf2_msgs/msg/TFMessage", ts, { transforms: tf });
    }
  }
  if (args.imu) {
    // At rest an accelerometer reads the reaction to gravity: +g along the world's up.
    const R = T_world_camera.R, g = 9.80665;
    const up = [R[6] * g, R[7] * g, R[8] * g];  // R^T (0, 0, g)
    const imu = (ts, a) => add("/camera/imu", "sensor_msgs/msg/Imu", ts, {
      header: header(ts, OPTICAL), orientation: { x: 0, y: 0, z: 0, w: 1 }, orientation_covariance: Array(9).fill(0),
      angular_velocity: { x: 0, y: 0, z: 0 }, angular_velocity_covariance: Array(9).fill(0),
      linear_acceleration: { x: a[0], y: a[1], z: a[2] }, linear_acceleration_covariance: Array(9).fill(0),
    });
    imu(t, up);
    imu(t + 10000000n, [up[0] + 3, up[1], up[2]]);
  }
  const img = crop(readPng16(name(n, "depth.png")));
  const hdr = header(t, OPTICAL);
  add("/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo", t, {
    header: hdr, height: args.fault === "size" ? img.height / 2 : img.height, width: args.fault === "size" ? img.width / 2 : img.width,
    distortion_model: "plumb_bob", d: distortion,
    k: [K[0], 0, K[2], 0, K[4], K[5], 0, 0, 1], r: [1, 0, 0, 0, 1, 0, 0, 0, 1], p: [K[0], 0, K[2], 0, 0, K[4], K[5], 0, 0, 0, 1, 0],
    binning_x: 0, binning_y: 0, roi: { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false },
  });
  if (args.depth === "16UC1" || args.depth === "32FC1") {
    const f32 = args.depth === "32FC1";
    const data = new Uint8Array(img.width * img.height * (f32 ? 4 : 2));
    const view = new DataView(data.buffer);
    for (let k = 0; k < img.pixels.length; ++k) {
      if (f32) view.setFloat32(4 * k, img.pixels[k] === 0 ? NaN : img.pixels[k] / 1000, true);
      else view.setUint16(2 * k, img.pixels[k], true);
    }
    add("/camera/depth/image_raw", "sensor_msgs/msg/Image", t, {
      header: hdr, height: img.height, width: img.width, encoding: args.depth, is_bigendian: args.fault === "bigendian" ? 1 : 0,
      step: img.width * (f32 ? 4 : 2) - (args.fault === "step" ? 2 : 0), data,
    });
  } else {
    // image_transport's compressedDepth: format (int32), two quantisation floats, a PNG.
    const f32 = args.depth === "compressed32";
    let png = args.crop ? encodePng16(img.width, img.height, img.pixels) : fs.readFileSync(name(n, "depth.png"));
    const head = Buffer.alloc(12);
    if (f32) {
      // Inverse depth quantised as the plugin does: value = A / depth + B.
      const A = 1000 * (1 - 0.3 / 10), B = -A / 10 + 1;  // depth 0.3..10 m
      head.writeFloatLE(A, 4); head.writeFloatLE(B, 8);
      const inv16 = new Uint16Array(img.pixels.length);
      for (let k = 0; k < inv16.length; ++k) inv16[k] = img.pixels[k] === 0 ? 0 : Math.round(A / (img.pixels[k] / 1000) + B);
      png = encodePng16(img.width, img.height, inv16);
    }
    add("/camera/depth/image_raw/compressedDepth", "sensor_msgs/msg/CompressedImage", t, {
      header: hdr, format: `${f32 ? "32FC1" : "16UC1"}; compressedDepth png`, data: new Uint8Array(Buffer.concat([head, png])),
    });
  }
  if (args["second-camera"]) {
    for (const m of messages.filter((x) => x.t === t && x.topic.startsWith("/camera/depth/"))) {
      messages.push({ ...m, topic: m.topic.replace("/camera/", "/camera2/") });
    }
  }
  if (args.colour) {
    const w = img.width, h = img.height;
    add("/camera/color/image_raw", "sensor_msgs/msg/Image", t, {
      header: header(t, "camera_color_optical_frame"), height: h, width: w, encoding: "rgb8", is_bigendian: 0, step: 3 * w, data: new Uint8Array(3 * w * h).fill(128),
    });
    add("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", t, {
      header: header(t, "camera_color_optical_frame"), height: h, width: w, distortion_model: "plumb_bob", d: [0.1, 0, 0, 0, 0],
      k: [600, 0, w / 2, 0, 600, h / 2, 0, 0, 1], r: [1, 0, 0, 0, 1, 0, 0, 0, 1], p: [600, 0, w / 2, 0, 0, 600, h / 2, 0, 0, 0, 1, 0],
      binning_x: 0, binning_y: 0, roi: { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false },
    });
  }
});
if (args["pad-mib"]) {
  const bytes = Number(args["pad-mib"]) * 1024 * 1024;
  numbers.forEach((n, i) => messages.push({ topic: "/padding", type: "mobmap_test/msg/Padding", t: stampOf(i), data: new Uint8Array(bytes) }));
  defs["mobmap_test/msg/Padding"] = "uint8[] data";
}
messages.sort((a, b) => (a.t < b.t ? -1 : a.t > b.t ? 1 : 0));

// A 16-bit greyscale PNG (no filtering) for compressed inverse depth.
function encodePng16(width, height, pixels) {
  const raw = Buffer.alloc(height * (1 + 2 * width));
  for (let y = 0; y < height; ++y) for (let x = 0; x < width; ++x) raw.writeUInt16BE(pixels[y * width + x], y * (1 + 2 * width) + 1 + 2 * x);
  const chunk = (type, body) => {
    const len = Buffer.alloc(4); len.writeUInt32BE(body.length);
    const tb = Buffer.concat([Buffer.from(type, "latin1"), body]);
    const crc = Buffer.alloc(4); crc.writeUInt32BE(zlib.crc32 ? zlib.crc32(tb) : crc32(tb));
    return Buffer.concat([len, tb, crc]);
  };
  const ihdr = Buffer.alloc(13); ihdr.writeUInt32BE(width, 0); ihdr.writeUInt32BE(height, 4); ihdr[8] = 16; ihdr[9] = 0;
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk("IHDR", ihdr), chunk("IDAT", zlib.deflateSync(raw)), chunk("IEND", Buffer.alloc(0))]);
}
function crc32(buf) {
  let c, crc = 0xffffffff;
  for (let n = 0; n < buf.length; n++) {
    c = (crc ^ buf[n]) & 0xff;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    crc = (crc >>> 8) ^ c;
  }
  return (crc ^ 0xffffffff) >>> 0;
}

// ---- out ---------------------------------------------------------------------------------------
if (args.feed) {
  const lines = messages.map((m) => JSON.stringify({ topic: m.topic, type: m.type, t: m.t.toString(), data: Buffer.from(m.data).toString("base64") }));
  fs.writeFileSync(args.feed, lines.join("\n") + "\n");
} else {
  await zstd.isLoaded;
  const chunks = args.chunks;
  const compress = chunks === "lz4" ? (d) => ({ compression: "lz4", compressedData: lz4.compress(d) })
    : chunks === "zstd" ? (d) => ({ compression: "zstd", compressedData: zstd.compress(d, 3) })
    : chunks === "plain" ? (d) => ({ compression: "", compressedData: d }) : undefined;
  const summary = args.summary === "yes";
  const fd = fs.openSync(args.out, "w");
  let position = 0n;
  const writable = { position: () => position, write: async (buf) => { fs.writeSync(fd, buf); position += BigInt(buf.byteLength); } };
  const writer = new McapWriter({
    writable, useChunks: chunks !== "none", compressChunk: compress, chunkSize: 1024 * 1024,
    useStatistics: summary, useSummaryOffsets: summary, useChunkIndex: summary, useMessageIndex: summary,
    repeatSchemas: summary, repeatChannels: summary, useAttachmentIndex: summary, useMetadataIndex: summary,
  });
  await writer.start({ profile: "ros2", library: "write_bag.mjs" });
  const channels = new Map();
  for (const m of messages) {
    if (!channels.has(m.topic)) {
      const schemaId = await writer.registerSchema({ name: m.type, encoding: "ros2msg", data: new TextEncoder().encode(defs[m.type]) });
      channels.set(m.topic, await writer.registerChannel({ topic: m.topic, schemaId, messageEncoding: "cdr", metadata: new Map() }));
    }
    await writer.addMessage({ channelId: channels.get(m.topic), sequence: 0, logTime: m.t, publishTime: m.t, data: m.data });
  }
  await writer.end();
  fs.closeSync(fd);
}
