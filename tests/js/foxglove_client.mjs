// A third-party Foxglove WebSocket client for the end-to-end test of `fleet foxglove`
// (tests/ground/test_foxglove_live.py): @foxglove/ws-protocol over `ws` connects,
// subscribes to the channels whose topic matches a regular expression, and decodes
// each message with the schema the server advertised (protobuf with protobufjs from
// the advertised FileDescriptorSet, JSON with JSON.parse), never with the project's
// own decoder. It prints one JSON object per line on stdout:
//   {"event": "open", "protocol": ...}
//   {"event": "serverInfo", "name", "capabilities"}
//   {"event": "advertise", "topic", "schemaName", "encoding", "schemaEncoding"}
//   {"event": "message", "topic", "schemaName", "message": {...decoded...}}
// and exits 0 after --count messages (0: runs until stopped; it exits 1 on an error, or
// after --timeout seconds with fewer messages).
//
// usage: node foxglove_client.mjs ws://127.0.0.1:PORT [--topics REGEX] [--count N]
//        [--timeout S] [--origin ORIGIN]
// (--origin: the Origin header a web page's browser would send; none by default)
import wsProtocol from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import "protobufjs/ext/descriptor.js";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const args = process.argv.slice(2);
const url = args[0];
const option = (name, fallback) => {
  const at = args.indexOf(name);
  return at >= 0 ? args[at + 1] : fallback;
};
const topics = new RegExp(option("--topics", "."));
const count = Number(option("--count", "10"));
const timeout = Number(option("--timeout", "60"));
const origin = option("--origin", undefined);

const print = (object) => process.stdout.write(JSON.stringify(object) + "\n");

// Subprotocols the SDK's server and the protocol library know, newest first.
const ws = new WebSocket(
  url,
  ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL],
  origin === undefined ? {} : { origin },
);
const client = new FoxgloveClient({ ws });
const decoders = new Map(); // subscription id -> {topic, schemaName, decode}
let received = 0;

function decoderFor(channel) {
  if (channel.encoding === "json") {
    const text = new TextDecoder();
    return (data) => JSON.parse(text.decode(data));
  }
  if (channel.encoding === "protobuf") {
    const descriptor = Buffer.from(channel.schema, "base64");
    const root = protobuf.Root.fromDescriptor(descriptor);
    const type = root.lookupType(channel.schemaName);
    return (data) =>
      type.toObject(type.decode(data), { longs: Number, enums: Number, defaults: true });
  }
  throw new Error(`unsupported message encoding ${channel.encoding} on ${channel.topic}`);
}

const timer =
  count > 0
    ? setTimeout(() => {
        print({ event: "timeout", received });
        process.exit(1);
      }, timeout * 1000)
    : undefined;

client.on("open", () => print({ event: "open", protocol: ws.protocol }));
client.on("serverInfo", (info) =>
  print({ event: "serverInfo", name: info.name, capabilities: info.capabilities }),
);
client.on("error", (error) => {
  print({ event: "error", error: String(error) });
  process.exit(1);
});
client.on("close", () => {
  print({ event: "close", received });
  process.exit(received >= count ? 0 : 1);
});
client.on("advertise", (channels) => {
  for (const channel of channels) {
    print({
      event: "advertise",
      topic: channel.topic,
      schemaName: channel.schemaName,
      encoding: channel.encoding,
      schemaEncoding: channel.schemaEncoding ?? null,
    });
    if (!topics.test(channel.topic)) continue;
    const id = client.subscribe(channel.id);
    decoders.set(id, {
      topic: channel.topic,
      schemaName: channel.schemaName,
      decode: decoderFor(channel),
    });
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const channel = decoders.get(subscriptionId);
  if (channel === undefined) return;
  const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  print({
    event: "message",
    topic: channel.topic,
    schemaName: channel.schemaName,
    message: channel.decode(bytes),
  });
  received += 1;
  if (count > 0 && received >= count) {
    clearTimeout(timer);
    process.exit(0);
  }
});
