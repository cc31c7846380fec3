#include "tls.h"

namespace occgeo::service {

std::shared_ptr<boost::asio::ssl::context> make_tls_context(const TlsConfig& tls) {
  namespace ssl = boost::asio::ssl;
  auto context = std::make_shared<ssl::context>(ssl::context::tls_server);
  // Only TLS 1.2 and 1.3: the older protocols have known attacks.
  context->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                       ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 | ssl::context::single_dh_use);
  boost::system::error_code error;
  context->use_certificate_chain_file(tls.cert.string(), error);
  if (error) throw ConfigError("configuration 'tls.cert': cannot use '" + tls.cert.string() + "': " + error.message());
  context->use_private_key_file(tls.key.string(), ssl::context::pem, error);
  if (error) throw ConfigError("configuration 'tls.key': cannot use '" + tls.key.string() + "': " + error.message());
  return context;
}

}  // namespace occgeo::service
