// Helpers the `occgeo` tool's commands share (cli_common.h).
#include "cli_common.h"

#include <google/protobuf/util/json_util.h>

#include <cstdio>
#include <iostream>
#include <string>

#include "occgeo/proto/protocol.h"

namespace occgeo::cli {

Connection connect_query(const Options& options) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("occgeo-cli");
  connection.hello(hello);
  return connection;
}

std::string fmt(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

void print_json(const google::protobuf::Message& reply) {
  google::protobuf::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;
  options.preserve_proto_field_names = true;
  std::string json;
  const auto status = google::protobuf::util::MessageToJsonString(reply, &json, options);
  if (!status.ok()) throw ClientError("cannot print the " + reply.GetTypeName() + " as JSON: " + status.ToString());
  std::cout << json << "\n";
}

}  // namespace occgeo::cli
