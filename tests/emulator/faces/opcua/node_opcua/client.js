// A small node-opcua client for nckemu's interop tests.
// usage: node client.js '<json>'   with {"url": ..., "user": ..., "password": ..., "ops": [...]}
// ops: {"read": "ns=2;s=/Channel/State/progStatus"}
//      {"write": "ns=2;s=...", "value": 1.5, "type": "Double"}
//      {"subscribe": "ns=2;s=...", "ms": 1500, "after_ms": 300}   (records changes; prints when done)
//      {"events": "i=2253", "fields": ["Message", "3:AlarmIdentifier", "ActiveState.Id"], "ms": 1500}   (records events)
//      {"browse": [["http://opcfoundation.org/UA/Machinery/", "Machines"], "*", [uri, "Monitoring"]]}
//          (from Objects by browse names, "*" the only child; later ops may name the node found "$browsed";
//           the result has its node id and type definition)
//      {"walk": "$browsed"}   (every variable below the node, depth first: its browse path, status, DataType
//          and the built-in type that DataType comes from, ValueRank, the value's variant type and array-ness,
//          and its EngineeringUnits property decoded, if it has one)
// optional: "security": "Basic256Sha256", "mode": "SignAndEncrypt" (or "Sign"), "pki": a folder for the client's own certificate
// Prints one line "RESULT <json>" (node-opcua logs on stdout too): a list with one result per op ({"status": "Good", "value": ...}).
"use strict";
const opcua = require("node-opcua-client");

// The built-in type a DataType comes from (its own id for a built-in one, 29 Enumeration, 22 Structure),
// following inverse HasSubtype references up the type tree.
async function builtInOf(session, dataType, cache) {
  const key = dataType.toString();
  if (cache.has(key)) return cache.get(key);
  let base = null;
  if (dataType.namespace === 0 && dataType.value <= 29) {
    base = dataType.value;
  } else {
    const up = await session.browse({
      nodeId: dataType, referenceTypeId: "HasSubtype", includeSubtypes: false,
      browseDirection: opcua.BrowseDirection.Inverse, resultMask: 63,
    });
    const parent = (up.references || [])[0];
    base = parent ? await builtInOf(session, parent.nodeId, cache) : null;
  }
  cache.set(key, base);
  return base;
}

async function walk(session, start) {
  const found = [];
  const cache = new Map();
  const visit = async (nodeId, path, depth) => {
    if (depth > 12) return;
    const result = await session.browse({
      nodeId, referenceTypeId: "HierarchicalReferences", includeSubtypes: true,
      browseDirection: opcua.BrowseDirection.Forward, resultMask: 63,
    });
    for (const ref of result.references || []) {
      const where = path + "/" + ref.browseName.name;
      if (ref.nodeClass === opcua.NodeClass.Variable) {
        const [value, dataType, valueRank] = await session.read([
          { nodeId: ref.nodeId, attributeId: opcua.AttributeIds.Value },
          { nodeId: ref.nodeId, attributeId: opcua.AttributeIds.DataType },
          { nodeId: ref.nodeId, attributeId: opcua.AttributeIds.ValueRank },
        ]);
        const entry = {
          path: where, status: value.statusCode.name, dataType: dataType.value.value.toString(),
          base: await builtInOf(session, dataType.value.value, cache), valueRank: valueRank.value.value,
          variant: value.value ? value.value.dataType : null,
          array: value.value ? value.value.arrayType !== opcua.VariantArrayType.Scalar : null,
        };
        if (ref.browseName.name === "EngineeringUnits" && value.value && value.value.value) {
          const unit = value.value.value;
          entry.eu = { namespaceUri: unit.namespaceUri, unitId: unit.unitId,
                       displayName: unit.displayName.text, description: unit.description.text };
        }
        found.push(entry);
      }
      if (ref.nodeClass === opcua.NodeClass.Object || ref.nodeClass === opcua.NodeClass.Variable) {
        await visit(ref.nodeId, where, depth + 1);
      }
    }
  };
  await visit(start, "", 0);
  return found;
}

async function main() {
  const job = JSON.parse(process.argv[2]);
  const options = { endpointMustExist: false, connectionStrategy: { maxRetry: 1 } };
  if (job.security) {
    options.securityPolicy = opcua.SecurityPolicy[job.security];
    options.securityMode = opcua.MessageSecurityMode[job.mode || "SignAndEncrypt"];
    const { OPCUACertificateManager } = require("node-opcua-certificate-manager");
    options.clientCertificateManager = new OPCUACertificateManager({ rootFolder: job.pki, automaticallyAcceptUnknownCertificate: true });
  }
  const client = opcua.OPCUAClient.create(options);
  await client.connect(job.url);
  const identity = job.user
    ? { type: opcua.UserTokenType.UserName, userName: job.user, password: job.password }
    : { type: opcua.UserTokenType.Anonymous };
  const session = await client.createSession(identity);
  const results = [];
  let browsed = null;
  const resolve = (id) => (id === "$browsed" ? browsed : id);
  try {
    for (const raw of job.ops) {
      const op = Object.assign({}, raw);
      for (const key of ["read", "subscribe", "events", "walk"]) if (op[key]) op[key] = resolve(op[key]);
      if (op.browse) {
        const namespaces = await session.readNamespaceArray();
        let nodeId = "i=85";
        let typeDefinition = null;
        for (const step of op.browse) {
          const result = await session.browse({
            nodeId, referenceTypeId: "HierarchicalReferences", includeSubtypes: true,
            browseDirection: opcua.BrowseDirection.Forward, resultMask: 63,
          });
          const refs = result.references || [];
          const found = step === "*" ? (refs.length === 1 ? refs[0] : null)
            : refs.find((r) => r.browseName.name === step[1] && namespaces[r.browseName.namespaceIndex] === step[0]);
          if (!found) throw new Error("browse: no " + JSON.stringify(step) + " below " + nodeId);
          nodeId = found.nodeId.toString();
          typeDefinition = found.typeDefinition.toString();
        }
        browsed = nodeId;
        const typeNode = await session.read({ nodeId: typeDefinition, attributeId: opcua.AttributeIds.BrowseName });
        results.push({ status: "Good", nodeId, typeDefinition: typeNode.value.value.name });
      } else if (op.walk) {
        results.push({ status: "Good", variables: await walk(session, op.walk) });
      } else if (op.read) {
        const dv = await session.read({ nodeId: op.read, attributeId: opcua.AttributeIds.Value });
        let value = dv.value ? dv.value.value : null;
        if (value && typeof value === "object" && value.length !== undefined) value = Array.from(value);
        results.push({ status: dv.statusCode.name, value });
      } else if (op.write) {
        const status = await session.write({
          nodeId: op.write, attributeId: opcua.AttributeIds.Value,
          value: { value: { dataType: opcua.DataType[op.type], value: op.value } },
        });
        results.push({ status: status.name });
      } else if (op.subscribe) {
        const subscription = await session.createSubscription2({
          requestedPublishingInterval: 100, requestedMaxKeepAliveCount: 10, publishingEnabled: true,
        });
        const item = await subscription.monitor(
          { nodeId: op.subscribe, attributeId: opcua.AttributeIds.Value },
          { samplingInterval: 100, queueSize: 10, discardOldest: true }, opcua.TimestampsToReturn.Both);
        const seen = [];
        item.on("changed", (dv) => seen.push(dv.value.value));
        // Tell the test when the subscription is live, so it writes over S7 only then.
        process.stdout.write("RESULT " + JSON.stringify({ subscribed: true }) + "\n");
        await new Promise((resolve) => setTimeout(resolve, op.ms));
        await subscription.terminate();
        results.push({ status: "Good", values: seen });
      } else if (op.events) {
        const subscription = await session.createSubscription2({
          requestedPublishingInterval: 100, requestedMaxKeepAliveCount: 10, publishingEnabled: true,
        });
        const item = await subscription.monitor(
          { nodeId: op.events, attributeId: opcua.AttributeIds.EventNotifier },
          { samplingInterval: 0, queueSize: 100, filter: opcua.constructEventFilter(op.fields) },
          opcua.TimestampsToReturn.Both);
        const seen = [];
        const plain = (variant) => {
          const value = variant.value;
          if (value && value.text !== undefined) return value.text;
          if (value && typeof value === "object" && value.length !== undefined) return Array.from(value);
          return value;
        };
        item.on("changed", (fields) => seen.push(fields.map(plain)));
        process.stdout.write("RESULT " + JSON.stringify({ subscribed: true }) + "\n");
        await new Promise((resolve) => setTimeout(resolve, op.ms));
        await subscription.terminate();
        results.push({ status: "Good", events: seen });
      }
    }
  } finally {
    await session.close();
    await client.disconnect();
  }
  process.stdout.write("RESULT " + JSON.stringify(results) + "\n");
}

main().catch((err) => {
  process.stdout.write("RESULT " + JSON.stringify({ error: String(err && err.message ? err.message : err) }) + "\n");
  process.exit(1);
});
