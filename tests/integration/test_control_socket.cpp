// SPDX-License-Identifier: Apache-2.0
// The local control socket (fovea/protocol/control_socket.h): a request is answered with the
// sender's credentials known; the file is created with the mode asked for and removed on the way
// out; a stale socket is replaced, a live one or a regular file is not; a client that connects
// and says nothing, or says something else, is dropped without stopping the next one; a peer
// without permission on the file is told so.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <grp.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "fovea/protocol/control_socket.h"
#include "temp_dir.h"

using namespace fovea::protocol;

namespace {

struct TempDir : fovea::test::TempDir {
  TempDir() : fovea::test::TempDir("fovea-ctlsock") {}
  std::string sock() const { return (path / "control.sock").string(); }
};

ControlReply echo(const ControlRequest& r, const PeerCredentials& who) {
  ControlReply out{r.command, ControlResult::Ok, {}};
  out.message.value = "uid " + std::to_string(who.uid) + " " + r.argument.value;
  return out;
}

ControlRequest request(const std::string& arg) {
  ControlRequest r{ControlCommand::LoadCalibration, {}};
  r.argument.value = arg;
  return r;
}

int connect_raw(const std::string& path) {
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::memcpy(a.sun_path, path.data(), path.size());
  EXPECT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
  return fd;
}

}  // namespace

TEST(ControlSocket, AnswersARequestKnowingWhoSentIt) {
  TempDir d;
  ControlSocket s(d.sock(), 0660, echo);
  std::string error;
  const auto r = send_local_control(d.sock(), request("cal.json"), 2000, error);
  ASSERT_TRUE(r) << error;
  EXPECT_EQ(r->result, ControlResult::Ok);
  EXPECT_EQ(r->command, ControlCommand::LoadCalibration);
  EXPECT_EQ(r->message.value, "uid " + std::to_string(::geteuid()) + " cal.json");
  EXPECT_EQ(s.stats().requests, 1u);
}

TEST(ControlSocket, HasTheModeAskedForAndIsRemovedOnTheWayOut) {
  TempDir d;
  {
    ControlSocket s(d.sock(), 0660, echo);
    struct stat st {};
    ASSERT_EQ(::lstat(d.sock().c_str(), &st), 0);
    EXPECT_TRUE(S_ISSOCK(st.st_mode));
    EXPECT_EQ(st.st_mode & 0777, 0660u);
  }
  EXPECT_FALSE(std::filesystem::exists(d.sock()));
}

TEST(ControlSocket, ReplacesAStaleSocketButNotALiveOneNorAFile) {
  TempDir d;
  {  // a socket file nobody listens on: what a killed daemon leaves
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, d.sock().data(), d.sock().size());
    ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
    ::close(fd);
  }
  ControlSocket s(d.sock(), 0660, echo);
  try {
    ControlSocket second(d.sock(), 0660, echo);
    FAIL() << "a second daemon took over a live socket";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("another fovea-trackerd answers on it"), std::string::npos) << e.what();
  }
  std::string error;
  EXPECT_TRUE(send_local_control(d.sock(), request("still"), 2000, error)) << error;
  const std::string file = (d.path / "file").string();
  std::ofstream(file) << "precious";
  try {
    ControlSocket third(file, 0660, echo);
    FAIL() << "replaced a regular file";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("exists and is not a socket"), std::string::npos) << e.what();
  }
  std::string content;
  std::getline(std::ifstream(file), content);
  EXPECT_EQ(content, "precious");
}

// Issue 23 item 3's starvation, locally: a silent or garbled client costs the next one at most
// the receive timeout, and never gets an answer.
TEST(ControlSocket, SilentAndGarbledClientsAreDroppedAndTheNextIsServed) {
  TempDir d;
  ControlSocket s(d.sock(), 0660, echo, 200);
  const int silent = connect_raw(d.sock());
  const int garbled = connect_raw(d.sock());
  ASSERT_EQ(::send(garbled, "hello", 5, 0), 5);
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  const auto r = send_local_control(d.sock(), request("after"), 3000, error);
  ASSERT_TRUE(r) << error;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(1500));
  char byte = 0;
  EXPECT_LE(::recv(garbled, &byte, 1, 0), 0);  // closed unanswered
  ::close(silent);
  ::close(garbled);
  EXPECT_EQ(s.stats().timed_out, 1u);
  EXPECT_EQ(s.stats().malformed, 1u);
}

// Issue 23 item 3: requests are rate-limited and still answered, never dropped silently.
TEST(ControlSocket, AFloodIsAnsweredButOnlyTheRateIsExecuted) {
  TempDir d;
  std::atomic<int> executed{0};
  ControlSocket s(d.sock(), 0660, [&](const ControlRequest& r, const PeerCredentials& who) {
    ++executed;
    return echo(r, who);
  });
  int refused = 0, answered = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 300; ++i) {
    std::string error;
    const auto r = send_local_control(d.sock(), request("x"), 2000, error);
    ASSERT_TRUE(r) << error;
    ++answered;
    if (r->result == ControlResult::Refused) {
      EXPECT_EQ(r->message.value, "too many control requests; nothing was done");
      ++refused;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(answered, 300);
  EXPECT_LE(executed.load(), static_cast<int>(ControlSocket::kMaxRequestsPerSecond * (1 + seconds)) + 1);
  EXPECT_EQ(refused + executed.load(), 300);
  EXPECT_EQ(s.stats().rate_limited, static_cast<std::uint64_t>(refused));
  if (seconds < 2) {
    EXPECT_GT(refused, 0) << "300 requests in " << seconds << " s were all executed";
  }
}

TEST(ControlSocket, AMissingSocketOrNoPermissionIsNamed) {
  TempDir d;
  std::string error;
  EXPECT_FALSE(send_local_control(d.sock(), request("x"), 500, error));
  EXPECT_NE(error.find("control socket " + d.sock()), std::string::npos) << error;
}

// Any local user is not an operator (issue 23 item 2): a process of another user, not in the
// socket's group, cannot connect. As root the test drops to nobody in a child; as another user it
// makes the socket its own only (0600) and has no second user to try from.
TEST(ControlSocket, AnotherUserCannotSendCommands) {
  TempDir d;
  ::chmod(d.path.c_str(), 0755);  // the directory is open; the socket's own mode must keep others out
  ControlSocket s(d.sock(), 0660, echo);
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to run a child as another user (nobody)";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(3);
    std::string error;
    const bool answered = send_local_control(d.sock(), request("x"), 500, error).has_value();
    ::_exit(!answered && error.find("permission denied") != std::string::npos ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "3: could not drop privileges; 1: nobody reached the daemon";
  EXPECT_EQ(s.stats().requests, 0u);
}

TEST(ControlSocket, DefaultPathsArePerPortAndPrivate) {
  const auto c = control_socket_candidates(4545);
  ASSERT_GE(c.size(), 2u);
  EXPECT_EQ(c.front(), "/run/fovea/control-4545.sock");
  EXPECT_EQ(c.back(), "/tmp/fovea-" + std::to_string(::geteuid()) + "/control-4545.sock");
  const std::string p = default_control_socket(4545);
  EXPECT_NE(std::find(c.begin(), c.end(), p), c.end()) << p;
}
