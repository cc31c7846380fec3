// What a browser sends the live view over its WebSocket is read as JSON, whatever the key order, spacing, escapes or
// extra keys; anything else gets an error naming the field, and changes nothing.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core.h"
#include "http/foxglove.h"
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

// A Foxglove client's subscribe and unsubscribe are read as JSON: key order, spacing and the extra keys the protocol
// allows change nothing (a pattern match on the text missed a subscription with an extra key and would have taken an
// "id" from any nested object).
TEST(FoxgloveMessages, SubscribeAndUnsubscribeAreReadAsJsonWhateverTheKeyOrderOrExtraKeys) {
  using http::foxglove::parse_client_request;
  const auto subscribe = parse_client_request(
      R"({ "subscriptions" : [ {"channelId": 1, "id": 7}, {"id": 8, "extra": {"id": 99}, "channelId": 2} ],)"
      R"( "op" : "subscribe" })");
  EXPECT_EQ(subscribe.op, "subscribe");
  EXPECT_TRUE(subscribe.problem.empty()) << subscribe.problem;
  ASSERT_EQ(subscribe.subscribe.size(), 2U);
  EXPECT_EQ(subscribe.subscribe[0].id, 7U);
  EXPECT_EQ(subscribe.subscribe[0].channel, 1U);
  EXPECT_EQ(subscribe.subscribe[1].id, 8U);
  EXPECT_EQ(subscribe.subscribe[1].channel, 2U);
  const auto unsubscribe = parse_client_request(R"({"subscriptionIds":[8, 7],"op":"unsubscribe"})");
  EXPECT_EQ(unsubscribe.op, "unsubscribe");
  EXPECT_EQ(unsubscribe.unsubscribe, (std::vector<std::uint32_t>{8, 7}));
  EXPECT_TRUE(unsubscribe.subscribe.empty());
  // Other ops of the protocol are recognised and ask for nothing here.
  const auto other = parse_client_request(R"({"op":"getParameters","parameterNames":[],"id":"a"})");
  EXPECT_EQ(other.op, "getParameters");
  EXPECT_TRUE(other.subscribe.empty() && other.unsubscribe.empty() && other.problem.empty());
}

TEST(FoxgloveMessages, WhatIsNotUnderstoodIsNamedAndSubscribesNothing) {
  using http::foxglove::parse_client_request;
  EXPECT_EQ(parse_client_request("subscribe 1").problem, "not a JSON object");
  EXPECT_EQ(parse_client_request(R"({"subscriptions":[]})").problem, R"(no "op" string)");
  EXPECT_EQ(parse_client_request(R"({"op":"subscribe"})").problem, R"(subscribe without a "subscriptions" array)");
  // A bad entry is skipped and named; the good ones still count.
  const auto mixed = parse_client_request(
      R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1},{"id":"3","channelId":1},{"id":4,"channelId":2}]})");
  ASSERT_EQ(mixed.subscribe.size(), 1U);
  EXPECT_EQ(mixed.subscribe[0].id, 4U);
  EXPECT_NE(mixed.problem.find("id"), std::string::npos);
  EXPECT_EQ(parse_client_request(R"({"op":"unsubscribe","subscriptionIds":[1.5]})").unsubscribe.size(), 0U);
}

}  // namespace
}  // namespace occgeo::service
