#pragma once

#include <boost/asio/ssl/context.hpp>
#include <memory>

#include "occgeo/service/config.h"

namespace occgeo::service {

// The server's TLS context from the configured PEM certificate chain and key (TLS 1.2 or later); throws
// ConfigError naming tls.cert or tls.key when a file cannot be used.
std::shared_ptr<boost::asio::ssl::context> make_tls_context(const TlsConfig& tls);

}  // namespace occgeo::service
