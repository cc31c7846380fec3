// What a browser sends the live view over its WebSocket is read as JSON, whatever the key order, spacing, escapes or
// extra keys; anything else gets an error naming the field, and changes nothing.
#include <gtest/gtest.h>

#include <string>

#include "core.h"
#include "http/live_view.h"
#include "occgeo/service/config.h"

namespace occgeo::service {
namespace {

class LiveViewMessages : public ::testing::Test {
 protected:
  LiveViewMessages() : core_(ServerConfig{}), view_(core_) {
    core_.add_world("lab", mapping::HimmGrid(core_.config().himm));
  }
  ServerCore core_;
  http::LiveViewState view_;
};

TEST_F(LiveViewMessages, SelectIsReadInAnyKeyOrderWithExtraKeys) {
  EXPECT_EQ(view_.handle_message(R"({"type":"select","world":"lab"})"), R"({"type":"selected"})");
  EXPECT_EQ(view_.handle_message(R"( { "world" : "lab", "client": {"v": [1, 2]}, "type" : "select" } )"),
            R"({"type":"selected"})");
  EXPECT_EQ(view_.handle_message(R"({"slice_z_m": 0.5, "type": "select"})"), R"({"type":"selected"})");
  EXPECT_EQ(view_.handle_message(R"({"type":"sel\u0065ct","world":"l\u0061b"})"), R"({"type":"selected"})")
      << "escapes are decoded";
}

TEST_F(LiveViewMessages, BadMessagesNameTheField) {
  const auto error_names = [&](const std::string& message, const std::string& field) {
    const std::string reply = view_.handle_message(message);
    EXPECT_NE(reply.find(R"("type":"error")"), std::string::npos) << message << " -> " << reply;
    EXPECT_NE(reply.find(R"("field":")" + field + "\""), std::string::npos) << message << " -> " << reply;
  };
  error_names("not json", "message");
  error_names(R"(["select"])", "message");
  error_names(R"({"world":"lab"})", "type");
  error_names(R"({"type":42})", "type");
  error_names(R"({"type":"dance"})", "type");
  error_names(R"({"type":"select","world":"moon"})", "world");
  error_names(R"({"type":"select","slice_z_m":"high"})", "slice_z_m");
  error_names(R"({"type":"select","slice_z_m":1e9})", "slice_z_m");
  error_names(R"({"type":"estop"})", "robot");
  error_names(R"({"type":"estop","robot":"nobody"})", "robot");
}

}  // namespace
}  // namespace occgeo::service
