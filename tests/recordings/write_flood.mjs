// Writes a hostile MCAP for mobmap's tests: one depth topic, then CHUNKS zstd chunks that
// each repeat one valid message (a SIDE x SIDE 16UC1 sensor_msgs/Image of 1 m depth; SIDE 1:
// 60 bytes) until the chunk holds MIB MiB. zstd stores a chunk in a few hundred bytes, so
// the file is small and expands to millions of images, or to thousands of large ones:
// what indexing and decoding a recording may cost must be bounded, not only what
// decompressing it costs.
//
//   node write_flood.mjs --out FILE.mcap [--chunks 32] [--mib 32] [--side 1]
import fs from "node:fs";
import { createRequire } from "node:module";
import { parse } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";

const require = createRequire(import.meta.url);
const zstd = require("@foxglove/wasm-zstd");

const args = {};
for (let i = 2; i + 1 < process.argv.length; i += 2) args[process.argv[i].replace(/^--/, "")] = process.argv[i + 1];
const chunks = Number(args.chunks ?? 32), mib = Number(args.mib ?? 32), side = Number(args.side ?? 1);

const SEP = "\n================================================================================\nMSG: ";
const imageDef = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data" +
  SEP + "std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id" + SEP + "builtin_interfaces/Time\nint32 sec\nuint32 nanosec";
const image = new MessageWriter(parse(imageDef, { ros2: true })).writeMessage({
  header: { stamp: { sec: 1700000000, nanosec: 0 }, frame_id: "cam" }, height: side, width: side, encoding: "16UC1", is_bigendian: 0,
  step: 2 * side, data: new Uint8Array(new Uint16Array(side * side).fill(1000).buffer),
});

const le = (value, bytes) => {
  const b = Buffer.alloc(bytes);
  if (bytes === 8) b.writeBigUInt64LE(BigInt(value)); else if (bytes === 4) b.writeUInt32LE(value); else b.writeUInt16LE(value);
  return b;
};
const str = (s) => Buffer.concat([le(Buffer.byteLength(s), 4), Buffer.from(s)]);
const record = (op, content) => Buffer.concat([Buffer.from([op]), le(content.length, 8), content]);

// Message record: channel 1, sequence, log and publish time, the image.
const message = record(0x05, Buffer.concat([le(1, 2), le(0, 4), le(1700000000n * 1000000000n, 8), le(1700000000n * 1000000000n, 8), Buffer.from(image)]));
const count = Math.floor((mib * 1024 * 1024) / message.length);
const records = Buffer.alloc(count * message.length);
for (let i = 0; i < count; ++i) message.copy(records, i * message.length);
await zstd.isLoaded;
const compressed = Buffer.from(zstd.compress(records, 19));
const chunk = record(0x06, Buffer.concat([le(0, 8), le(0, 8), le(records.length, 8), le(0, 4), str("zstd"), le(compressed.length, 8), compressed]));

const out = [Buffer.from([0x89, 0x4d, 0x43, 0x41, 0x50, 0x30, 0x0d, 0x0a]), record(0x01, Buffer.concat([str("ros2"), str("write_flood.mjs")])),
  record(0x03, Buffer.concat([le(1, 2), str("sensor_msgs/msg/Image"), str("ros2msg"), le(Buffer.byteLength(imageDef), 4), Buffer.from(imageDef)])),
  record(0x04, Buffer.concat([le(1, 2), le(1, 2), str("/camera/depth/image_raw"), str("cdr"), le(0, 4)]))];
for (let i = 0; i < chunks; ++i) out.push(chunk);
out.push(record(0x0f, le(0, 4)));
fs.writeFileSync(args.out, Buffer.concat(out));
console.log(`${args.out}: ${chunks} chunks of ${count} images (${records.length} bytes, ${compressed.length} stored each)`);
