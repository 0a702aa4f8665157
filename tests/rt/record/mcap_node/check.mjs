// Opens a trainer session recording with the reference MCAP reader (@mcap/core, TypeScript):
// the streaming reader over every record with chunk CRCs validated, then the indexed reader
// through the summary (statistics, chunk and metadata indexes, message indexes). Checks the
// cycle channel, the session metadata and the number of cycle messages.
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
let session;
let lastCycle = -1n;
for (let record; (record = stream.nextRecord()); ) {
  counts[record.type] = (counts[record.type] ?? 0) + 1;
  if (record.type === "Channel" && record.topic === "/trainer/cycle") cycleChannel = record;
  if (record.type === "Metadata" && record.name === "session") session = record.metadata;
  if (record.type === "Message" && cycleChannel && record.channelId === cycleChannel.id) {
    if (record.data.byteLength !== Number(cycleChannel.metadata.get("record_bytes")))
      fail(`message of ${record.data.byteLength} bytes`);
    const cycle = new DataView(record.data.buffer, record.data.byteOffset).getBigUint64(0, true);
    if (cycle !== lastCycle + 1n) fail(`cycle ${cycle} after ${lastCycle}`);
    lastCycle = cycle;
  }
}
if (!stream.done()) fail("the stream reader did not reach the end of the file");
if (!cycleChannel) fail("no /trainer/cycle channel");
if (!session || !session.get("scene_text")) fail("no session metadata with the scene text");
if (BigInt(counts.Message ?? 0) !== expected)
  fail(`${counts.Message} messages, expected ${expected}`);

// 2. Indexed: through the footer and summary.
const readable = {
  size: async () => BigInt(bytes.byteLength),
  read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
};
const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
if (indexed.statistics?.messageCount !== expected)
  fail(`statistics say ${indexed.statistics?.messageCount} messages`);
let indexedMessages = 0n;
for await (const message of indexed.readMessages({ validateCrcs: true })) {
  if (message.channelId !== cycleChannel.id) fail("a message on another channel");
  indexedMessages += 1n;
}
if (indexedMessages !== expected) fail(`indexed reader read ${indexedMessages} messages`);
const names = [];
for await (const metadata of indexed.readMetadata()) names.push(metadata.name);
if (!names.includes("session") || !names.includes("session_end"))
  fail(`metadata records: ${names.join(", ")}`);
console.log(
  `mcap check ${file}: ${expected} cycle messages in ${indexed.chunkIndexes.length} chunks, ` +
    `records ${JSON.stringify(counts)}, metadata ${names.join(", ")}, scene ` +
    `'${session.get("scene_name")}'`,
);
