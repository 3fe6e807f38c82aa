// Rewrites an MCAP recording with independent tools: every message decoded by Foxglove's CDR
// reader and serialised again by its CDR writer, written by the official TypeScript McapWriter
// (zstd chunks from wasm-zstd). No metadata.yaml: a lone .mcap file.
import { McapIndexedReader, McapWriter } from "@mcap/core";
import { FileHandleReadable, FileHandleWritable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader, MessageWriter } from "@foxglove/rosmsg2-serialization";
import zstd from "@foxglove/wasm-zstd";
import { open } from "node:fs/promises";

const [input, output] = process.argv.slice(2);
await zstd.isLoaded;
const decompressHandlers = await loadDecompressHandlers();
const inHandle = await open(input, "r");
const reader = await McapIndexedReader.Initialize({ readable: new FileHandleReadable(inHandle), decompressHandlers });
const outHandle = await open(output, "w");
const writer = new McapWriter({
  writable: new FileHandleWritable(outHandle),
  useStatistics: true, useChunks: true, useChunkIndex: true, useMessageIndex: true, useSummaryOffsets: true,
  chunkSize: 1024 * 1024,
  compressChunk: (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) }),
});
await writer.start({ profile: "ros2", library: "mcap-ts rewrite" });
const map = new Map();
for await (const m of reader.readMessages()) {
  if (!map.has(m.channelId)) {
    const ch = reader.channelsById.get(m.channelId);
    const schema = reader.schemasById.get(ch.schemaId);
    const defs = parse(new TextDecoder().decode(schema.data), { ros2: true });
    const schemaId = await writer.registerSchema({ name: schema.name, encoding: "ros2msg", data: schema.data });
    const channelId = await writer.registerChannel({ topic: ch.topic, messageEncoding: "cdr", schemaId, metadata: new Map() });
    map.set(m.channelId, { channelId, r: new MessageReader(defs), w: new MessageWriter(defs) });
  }
  const c = map.get(m.channelId);
  const data = c.w.writeMessage(c.r.readMessage(m.data));
  await writer.addMessage({ channelId: c.channelId, sequence: m.sequence, logTime: m.logTime, publishTime: m.publishTime, data });
}
await writer.end();
await outHandle.close();
await inHandle.close();
console.log("wrote", output);
