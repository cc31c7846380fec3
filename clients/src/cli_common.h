#pragma once

// Helpers the `occgeo` tool's commands share: the query connection, number formatting, and reading the models, the
// footprint and the pose a command's options name.

#include <optional>
#include <string>
#include <vector>

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

// "grid,octomap,ptem" as Model values; throws UsageError for an unknown name.
std::vector<v1::Model> models_from(const Options& options);

// A Model's name as --models spells it; empty for an unknown value.
std::string model_name(v1::Model model);

// The --footprint option as a Footprint message; nullopt when absent. Throws UsageError when malformed.
std::optional<v1::Footprint> footprint_from(const Options& options);

// --x, --y and --theta (default 0) as a pose.
v1::Pose2D pose_from(const Options& options);

}  // namespace occgeo::cli
