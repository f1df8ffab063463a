// SPDX-License-Identifier: Apache-2.0
// Who fovea-monitor answers (monitor/request_checks.h): the Host header names the monitor (DNS
// rebinding), a WebSocket's Origin is the monitor's own page (cross-site WebSocket hijacking), the
// token matches; each rule alone, with the malformed inputs a hostile client would try.
#include <gtest/gtest.h>

#include "request_checks.h"

using namespace fovea::monitor;

TEST(MonitorChecks, HostHeaderSyntax) {
  EXPECT_EQ(parse_host("127.0.0.1:47880")->host, "127.0.0.1");
  EXPECT_EQ(*parse_host("127.0.0.1:47880")->port, 47880);
  EXPECT_EQ(parse_host("LocalHost")->host, "localhost");
  EXPECT_FALSE(parse_host("localhost")->port);
  EXPECT_EQ(parse_host("[::1]:8080")->host, "::1");
  for (const char* bad : {"", ":80", "a b", "host:", "host:0", "host:65536", "host:80x", "[::1", "[]:80", "[::1]x",
                          "ho/st", "host:80:80", "ev\til"}) {
    EXPECT_FALSE(parse_host(bad)) << bad;
  }
  EXPECT_FALSE(parse_host(std::string(300, 'a')));
}

TEST(MonitorChecks, OnlyNamesTheMonitorIsReachedByPass) {
  const AllowedHosts loopback = allowed_hosts("127.0.0.1", {});
  for (const char* ok : {"127.0.0.1:47880", "localhost:47880", "LOCALHOST:9000", "[::1]:47880", "127.1.2.3:1", "localhost"}) {
    EXPECT_TRUE(host_allowed(ok, loopback)) << ok;
  }
  // DNS rebinding: a name that resolves to 127.0.0.1 is still refused by name.
  for (const char* bad : {"evil.example:47880", "127.0.0.1.evil.example", "localhost.evil.example:47880",
                          "192.168.1.5:47880", "128.0.0.1:47880", "127.0.0.256:1", "127.0.0:1", "", "0.0.0.0:47880"}) {
    EXPECT_FALSE(host_allowed(bad, loopback)) << bad;
  }
  const AllowedHosts lan = allowed_hosts("192.168.1.5", {"eyes.lab.example"});
  EXPECT_TRUE(host_allowed("192.168.1.5:47880", lan));
  EXPECT_TRUE(host_allowed("eyes.lab.example", lan));
  EXPECT_FALSE(host_allowed("192.168.1.6:47880", lan));
  EXPECT_THROW(allowed_hosts("127.0.0.1", {"name:80"}), std::invalid_argument);
  EXPECT_THROW(allowed_hosts("127.0.0.1", {"bad name"}), std::invalid_argument);
}

TEST(MonitorChecks, AWebSocketMustComeFromTheMonitorsOwnPage) {
  EXPECT_TRUE(origin_allowed("http://127.0.0.1:47880", "127.0.0.1:47880"));
  EXPECT_TRUE(origin_allowed("HTTP://localhost:47880", "localhost:47880"));
  EXPECT_TRUE(origin_allowed(std::nullopt, "127.0.0.1:47880")) << "not a browser: the token still decides";
  for (const char* bad : {"http://evil.example", "http://127.0.0.1:47881", "https://127.0.0.1:47880", "null", "",
                          "http://localhost:47880", "http://127.0.0.1", "file://", "http://127.0.0.1:47880/x"}) {
    EXPECT_FALSE(origin_allowed(std::string_view(bad), "127.0.0.1:47880")) << bad;
  }
}

TEST(MonitorChecks, TheTokenDecides) {
  const std::string token = new_token();
  EXPECT_EQ(token.size(), 32u);
  EXPECT_NE(token, new_token());
  EXPECT_EQ(token_of("/ws?token=" + token), token);
  EXPECT_EQ(token_of("/ws?x=1&token=" + token + "&y=2"), token);
  EXPECT_EQ(token_of("/ws"), "");
  EXPECT_EQ(token_of("/ws?tokenx=1"), "");
  EXPECT_TRUE(token_matches(token, token));
  EXPECT_FALSE(token_matches(token.substr(1), token));
  EXPECT_FALSE(token_matches("", ""));
  EXPECT_FALSE(token_matches(std::string(32, '0'), token));
  EXPECT_EQ(path_of("/ws?token=1"), "/ws");
  EXPECT_EQ(path_of("/"), "/");
}
