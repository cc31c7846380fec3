#pragma once

// HTTP helpers for tests of occgeod's HTTP side (live view, /metrics): the port the server logged, and one GET.
// Header-only so that only the tests that use it need Boost.Beast.

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "process.h"

namespace occgeo::testing {

// The HTTP port the server logged (tests ask for port 0, so the kernel picks a free one); waits up to 4 s for it.
inline std::uint16_t http_port(const ServerProcess& server) {
  for (int attempt = 0; attempt < 200; ++attempt) {
    std::istringstream log(server.log());
    for (std::string line; std::getline(log, line);) {
      const auto event = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
      if (event.is_object() && event.value("event", "") == "http_listening" && event.contains("port") &&
          event["port"].is_number_unsigned()) {
        return event["port"].get<std::uint16_t>();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  throw std::runtime_error("occgeod did not log http_listening: " + server.log());
}

struct HttpResult {
  unsigned status = 0;
  std::string content_type;
  std::string body;
};

// GET http://127.0.0.1:PORT/TARGET, bounded by a 10 s deadline.
inline HttpResult http_get(std::uint16_t port, const std::string& target) {
  namespace beast = boost::beast;
  boost::asio::io_context io;
  beast::tcp_stream stream(io);
  stream.expires_after(std::chrono::seconds(10));
  stream.connect(boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
  beast::http::request<beast::http::empty_body> request{beast::http::verb::get, target, 11};
  request.set(beast::http::field::host, "127.0.0.1");
  beast::http::write(stream, request);
  beast::flat_buffer buffer;
  beast::http::response<beast::http::string_body> response;
  beast::http::read(stream, buffer, response);
  const auto content_type = response[beast::http::field::content_type];
  return {response.result_int(), std::string(content_type.data(), content_type.size()), response.body()};
}

}  // namespace occgeo::testing
