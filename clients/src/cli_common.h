#pragma once

// Helpers the `occgeo` tool's commands share: the query connection and number formatting.

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

}  // namespace occgeo::cli
