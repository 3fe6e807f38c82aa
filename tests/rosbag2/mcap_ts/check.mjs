// Independent check of an MCAP file with the official TypeScript MCAP library and Foxglove's
// ROS 2 CDR deserializer: stream read with CRCs, indexed read, every message decoded.
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { open, readFile } from "node:fs/promises";

const path = process.argv[2];
const decompressHandlers = await loadDecompressHandlers();
// 1. Streamed, every record, CRCs validated.
const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
const bytes = await readFile(path);
stream.append(bytes);
const ops = {};
for (let r; (r = stream.nextRecord()); ) ops[r.type] = (ops[r.type] ?? 0) + 1;
if (!stream.done()) throw new Error("stream reader: not done");
console.log("stream:", JSON.stringify(ops));
// 2. Indexed.
const handle = await open(path, "r");
const reader = await McapIndexedReader.Initialize({ readable: new FileHandleReadable(handle), decompressHandlers });
console.log("profile", reader.header.profile, "library", reader.header.library, "chunks", reader.chunkIndexes.length,
            "statistics", reader.statistics ? Number(reader.statistics.messageCount) : "none",
            "metadata", reader.metadataIndexes.map((m) => m.name).join(","));
const readers = new Map();
const counts = {};
const samples = {};
let last = -1n, ordered = true;
for await (const m of reader.readMessages({ validateCrcs: true })) {
  const ch = reader.channelsById.get(m.channelId);
  const schema = reader.schemasById.get(ch.schemaId);
  if (!readers.has(ch.id)) {
    const text = new TextDecoder().decode(schema.data);
    readers.set(ch.id, new MessageReader(parse(text, { ros2: true })));
  }
  const msg = readers.get(ch.id).readMessage(m.data);
  counts[ch.topic] = (counts[ch.topic] ?? 0) + 1;
  if (m.logTime < last) ordered = false;
  last = m.logTime;
  if (!samples[ch.topic]) {
    const s = { type: schema.name, encoding: ch.messageEncoding, qos: (ch.metadata.get("offered_qos_profiles") ?? "").slice(0, 12) };
    if (msg.header) s.stamp = `${msg.header.stamp.sec}.${msg.header.stamp.nanosec}`;
    if (msg.encoding !== undefined) Object.assign(s, { width: msg.width, height: msg.height, enc: msg.encoding, step: msg.step, bytes: msg.data.length });
    if (msg.format !== undefined) Object.assign(s, { format: msg.format, bytes: msg.data.length });
    if (msg.k) Object.assign(s, { k: Array.from(msg.k).slice(0, 3), d: Array.from(msg.d), model: msg.distortion_model });
    if (msg.transforms) Object.assign(s, { tf: msg.transforms.length, child: msg.transforms[0].child_frame_id, t: msg.transforms[0].transform.translation });
    if (typeof msg.data === "string") s.text = msg.data.slice(0, 30);
    samples[ch.topic] = s;
  }
}
console.log("indexed, in log-time order:", ordered, JSON.stringify(counts));
for (const [t, s] of Object.entries(samples)) console.log(" ", t, JSON.stringify(s));
await handle.close();
