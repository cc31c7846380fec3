#pragma once

#include <span>
#include <string_view>

namespace occgeo::service::http {

// A file of the live view page, compiled in from service/web at build time (web_assets.cc is generated).
struct WebAsset {
  std::string_view path;  // as requested, e.g. "/app.js"
  std::string_view content_type;
  std::string_view body;
};

[[nodiscard]] std::span<const WebAsset> web_assets();

}  // namespace occgeo::service::http
