// Independent decoder of an sms recording, for tests/test_recording_node.py: @mcap/core's stream
// reader (CRCs checked) with @mcap/support's decompressors, and protobufjs on the FileDescriptorSet
// stored in the file (what Foxglove does). Prints {topic: [[log time ns, message], ...]} as JSON;
// non-finite numbers as the strings "NaN", "Infinity", "-Infinity".
import { readFileSync } from "node:fs";
import { McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers, protobufFromBinaryDescriptor } from "@mcap/support";

const reader = new McapStreamReader({ decompressHandlers: await loadDecompressHandlers(), validateCrcs: true });
reader.append(readFileSync(process.argv[2]));
const schemas = new Map();
const channels = new Map();
const types = new Map();
const out = {};
const text = new TextDecoder();
for (let rec = reader.nextRecord(); rec; rec = reader.nextRecord()) {
  if (rec.type === "Schema") schemas.set(rec.id, rec);
  else if (rec.type === "Channel") channels.set(rec.id, rec);
  else if (rec.type === "Message") {
    const ch = channels.get(rec.channelId);
    let value;
    if (ch.messageEncoding === "protobuf") {
      let type = types.get(ch.schemaId);
      if (!type) {
        const s = schemas.get(ch.schemaId);
        type = protobufFromBinaryDescriptor(s.data).lookupType(s.name);
        types.set(ch.schemaId, type);
      }
      value = type.toObject(type.decode(rec.data), { longs: String, defaults: true });
    } else if (ch.messageEncoding === "json") {
      value = JSON.parse(text.decode(rec.data));
    } else {
      throw new Error(`unexpected message encoding ${ch.messageEncoding} on ${ch.topic}`);
    }
    (out[ch.topic] ??= []).push([rec.logTime.toString(), value]);
  }
}
if (!reader.done()) throw new Error("the stream reader did not reach the end of the file");
process.stdout.write(JSON.stringify(out, (_, v) => (typeof v === "number" && !Number.isFinite(v) ? String(v) : v)));
