// Opens a trainer session recording with the reference MCAP reader (@mcap/core, TypeScript):
// the streaming reader over every record with chunk CRCs validated, then the indexed reader
// through the summary (statistics, chunk and metadata indexes, message indexes). Checks the
// cycle channel, the session metadata and the number of cycle messages; the telemetry-frame
// channel (2) is counted and must agree between the two readers and the statistics.
// Usage: node check.mjs FILE EXPECTED_CYCLES      (exit 0 ok, 1 a check failed)
import { readFile } from "node:fs/promises";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { decompress } from "fzstd";

const [file, expectedText] = process.argv.slice(2);
const expected = BigInt(expectedText);
const bytes = new Uint8Array(await readFile(file));
const decompressHandlers = {
  zstd: (buffer, size) => decompress(buffer, new Uint8Array(Number(size))),
};
const fail = (message) => {
  console.error(`mcap check ${file}: ${message}`);
  process.exit(1);
};

// 1. Stream: every record in order, chunk CRCs checked.
const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
stream.append(bytes);
const counts = {};
let cycleChannel;
let telemetryChannel;
let cycleMessages = 0n;
let telemetryMessages = 0n;
let session;
let lastCycle = -1n;
for (let record; (record = stream.nextRecord()); ) {
  counts[record.type] = (counts[record.type] ?? 0) + 1;
  if (record.type === "Channel" && record.topic === "/trainer/cycle") cycleChannel = record;
  if (record.type === "Channel" && record.topic === "/trainer/telemetry") telemetryChannel = record;
  if (record.type === "Message" && telemetryChannel && record.channelId === telemetryChannel.id)
    telemetryMessages += 1n;
  if (record.type === "Metadata" && record.name === "session") session = record.metadata;
  if (record.type === "Message" && cycleChannel && record.channelId === cycleChannel.id) {
    if (record.data.byteLength !== Number(cycleChannel.metadata.get("record_bytes")))
      fail(`message of ${record.data.byteLength} bytes`);
    const cycle = new DataView(record.data.buffer, record.data.byteOffset).getBigUint64(0, true);
    if (cycle !== lastCycle + 1n) fail(`cycle ${cycle} after ${lastCycle}`);
    lastCycle = cycle;
    cycleMessages += 1n;
  }
}
if (!stream.done()) fail("the stream reader did not reach the end of the file");
if (!cycleChannel) fail("no /trainer/cycle channel");
if (!session || !session.get("scene_text")) fail("no session metadata with the scene text");
if (cycleMessages !== expected) fail(`${cycleMessages} cycle messages, expected ${expected}`);
if (BigInt(counts.Message ?? 0) !== expected + telemetryMessages)
  fail(`${counts.Message} messages, expected ${expected} + ${telemetryMessages} telemetry frames`);

// 2. Indexed: through the footer and summary.
const readable = {
  size: async () => BigInt(bytes.byteLength),
  read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
};
const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
if (indexed.statistics?.messageCount !== expected + telemetryMessages)
  fail(`statistics say ${indexed.statistics?.messageCount} messages`);
let indexedMessages = 0n;
let indexedTelemetry = 0n;
for await (const message of indexed.readMessages({ validateCrcs: true })) {
  if (message.channelId === cycleChannel.id) indexedMessages += 1n;
  else if (telemetryChannel && message.channelId === telemetryChannel.id) indexedTelemetry += 1n;
  else fail("a message on another channel");
}
if (indexedMessages !== expected) fail(`indexed reader read ${indexedMessages} messages`);
if (indexedTelemetry !== telemetryMessages)
  fail(`indexed reader read ${indexedTelemetry} telemetry frames, the stream ${telemetryMessages}`);
const names = [];
for await (const metadata of indexed.readMetadata()) names.push(metadata.name);
if (!names.includes("session") || !names.includes("session_end"))
  fail(`metadata records: ${names.join(", ")}`);
console.log(
  `mcap check ${file}: ${expected} cycle messages and ${telemetryMessages} telemetry frames in ` +
    `${indexed.chunkIndexes.length} chunks, ` +
    `records ${JSON.stringify(counts)}, metadata ${names.join(", ")}, scene ` +
    `'${session.get("scene_name")}'`,
);
