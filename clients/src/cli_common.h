#pragma once

// Helpers the `occgeo` tool's commands share: the query connection, number formatting and JSON output.

#include <google/protobuf/message.h>
#include <string>

#include "cli_commands.h"
#include "occgeo/client/connection.h"
#include "occgeo/client/json.h"

namespace occgeo::cli {

using occgeo::client::ClientError;
using occgeo::client::Connection;
using occgeo::client::Endpoint;
using occgeo::client::json_string;
namespace v1 = occgeo::v1;

// A connection to --server (default 127.0.0.1:7700) that has said hello as a query client.
Connection connect_query(const Options& options);

// A number for text and JSON output: six significant digits.
std::string fmt(double v);

// Prints a reply as --json shows it, one line: protobuf's JSON printer with the .proto file's field names, every
// scalar field printed (false and 0 too), enums by name (MODEL_GRID) and 64-bit integers as strings, as proto3's JSON
// mapping has them; unset messages are left out. The schema (proto/occgeo/v1/*.proto) documents every key.
void print_json(const google::protobuf::Message& reply);

}  // namespace occgeo::cli
