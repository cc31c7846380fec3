#include "session.h"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>

#include "occgeo/service/log.h"

namespace occgeo::service {

Session::Session(ServerCore& core, asio::ip::tcp::socket socket, std::uint64_t id)
    : core_(core), socket_(std::move(socket)), decoder_(core.config().limits.max_frame_bytes) {
  info_.id = id;
  boost::system::error_code ignored;
  const auto remote = socket_.remote_endpoint(ignored);
  info_.peer = remote.address().to_string() + ":" + std::to_string(remote.port());
  ++core_.sessions;
}

Session::~Session() { --core_.sessions; }

void Session::start() {
  boost::system::error_code ignored;
  socket_.set_option(asio::ip::tcp::no_delay(true), ignored);
  log::info("session_open", {{"session", info_.id}, {"peer", info_.peer}});
  read_more();
}

void Session::close() {
  asio::dispatch(socket_.get_executor(), [self = shared_from_this()] { self->shutdown(); });
}

void Session::read_more() {
  socket_.async_read_some(asio::buffer(read_buffer_),
                          [self = shared_from_this()](const boost::system::error_code& error, std::size_t size) {
                            self->on_read(error, size);
                          });
}

void Session::on_read(const boost::system::error_code& error, std::size_t size) {
  if (closed_) return;
  if (error) {
    if (decoder_.buffered() > 0) {
      log::warn("session_truncated_frame", {{"session", info_.id}, {"buffered_bytes", decoder_.buffered()}});
    }
    shutdown();
    return;
  }
  decoder_.append(read_buffer_.data(), size);
  while (!closed_ && !close_after_write_) {
    v1::ClientMessage message;
    const proto::FrameStatus status = decoder_.next(message);
    if (status == proto::FrameStatus::need_more) break;
    if (status == proto::FrameStatus::too_large) {
      fail_stream(v1::ERROR_FRAME_TOO_LARGE, "frame of " + std::to_string(decoder_.rejected_frame_bytes()) +
                                                 " bytes is over the limit of " +
                                                 std::to_string(core_.config().limits.max_frame_bytes));
      return;
    }
    if (status == proto::FrameStatus::malformed) {
      fail_stream(v1::ERROR_BAD_FRAME, "the frame does not decode as an occgeo.v1 ClientMessage");
      return;
    }
    dispatch(shared_from_this(), std::move(message));
  }
  if (!closed_ && !close_after_write_) read_more();
}

void Session::send(v1::ServerMessage message) {
  // Encoding happens on the caller's thread so the network strand only moves bytes.
  std::string frame = proto::encode_frame(message);
  asio::dispatch(socket_.get_executor(),
                 [self = shared_from_this(), frame = std::move(frame)]() mutable { self->enqueue(std::move(frame)); });
}

void Session::enqueue(std::string frame) {
  if (closed_) return;
  outbox_bytes_ += frame.size();
  outbox_.push_back(std::move(frame));
  if (outbox_bytes_ > core_.config().limits.max_send_queue_bytes) {
    log::warn("session_slow_client_dropped",
              {{"session", info_.id}, {"peer", info_.peer}, {"unsent_bytes", outbox_bytes_}});
    shutdown();
    return;
  }
  if (!writing_) write_next();
}

void Session::write_next() {
  if (outbox_.empty()) {
    writing_ = false;
    if (close_after_write_) shutdown();
    return;
  }
  writing_ = true;
  asio::async_write(socket_, asio::buffer(outbox_.front()),
                    [self = shared_from_this()](const boost::system::error_code& error, std::size_t) {
                      if (self->closed_) return;
                      if (error) {
                        self->shutdown();
                        return;
                      }
                      self->outbox_bytes_ -= self->outbox_.front().size();
                      self->outbox_.pop_front();
                      self->write_next();
                    });
}

void Session::fail_stream(v1::ErrorCode code, const std::string& message) {
  log::warn("session_bad_stream", {{"session", info_.id}, {"peer", info_.peer}, {"error", message}});
  v1::ServerMessage reply;
  reply.mutable_error()->set_code(code);
  reply.mutable_error()->set_message(message + "; closing the connection");
  enqueue(proto::encode_frame(reply));
  close_after_write_ = true;
  if (!writing_) shutdown();
}

void Session::shutdown() {
  if (closed_) return;
  closed_ = true;
  boost::system::error_code ignored;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  socket_.close(ignored);
  outbox_.clear();
  outbox_bytes_ = 0;
  handle_disconnect(core_, info_);
  log::info("session_closed", {{"session", info_.id}, {"peer", info_.peer}});
}

}  // namespace occgeo::service
