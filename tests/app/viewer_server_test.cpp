// The live viewer's server against bad requests and bad clients: unknown paths, path traversal,
// other methods, malformed HTTP, malformed and oversized WebSocket frames, a client that never
// reads, several clients at once, a port in use, a bad bind address. Raw sockets, so that the
// bytes sent are exactly the bad ones. And the viewer's occupancy message decoded back to the
// snapshot it was made of.
#include "mcslam/app/viewer_server.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "mcslam/app/viewer.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/mapping/worker.hpp"

namespace mcslam::app {
namespace {

using Clock = std::chrono::steady_clock;

class Socket {
 public:
  explicit Socket(int port, int receive_buffer = 0) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (receive_buffer > 0)
      ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof(receive_buffer));
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0;
  }
  ~Socket() { ::close(fd_); }
  bool connected() const { return connected_; }
  void send(const std::string& bytes) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return;
      sent += static_cast<std::size_t>(n);
    }
  }
  /// Everything until the peer closes or `timeout_ms` passes (or `until` appears).
  std::string receive(int timeout_ms, const std::string& until = "") {
    std::string out = std::move(leftover);
    leftover.clear();
    if (!until.empty() && out.find(until) != std::string::npos) return out;
    const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
    while (Clock::now() < end) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      char buffer[65536];
      const ssize_t n = ::recv(fd_, buffer, sizeof(buffer), 0);
      if (n <= 0) {
        closed_ = true;
        break;
      }
      out.append(buffer, static_cast<std::size_t>(n));
      if (!until.empty() && out.find(until) != std::string::npos) break;
    }
    return out;
  }
  bool closed() const { return closed_; }
  std::string leftover;  // received after the handshake's reply, for the next receive()

 private:
  int fd_ = -1;
  bool connected_ = false;
  bool closed_ = false;
};

std::string get(int port, const std::string& request_line) {
  Socket s(port);
  s.send(request_line + "\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  return s.receive(3000);
}

/// A client frame: FIN, the opcode, masked with a zero key (so the payload is as given).
std::string client_frame(std::uint8_t opcode, const std::string& payload, bool masked = true) {
  std::string f;
  f.push_back(static_cast<char>(0x80 | opcode));
  const std::uint8_t mask_bit = masked ? 0x80 : 0x00;
  if (payload.size() < 126) {
    f.push_back(static_cast<char>(mask_bit | payload.size()));
  } else if (payload.size() < 65536) {
    f.push_back(static_cast<char>(mask_bit | 126));
    f.push_back(static_cast<char>(payload.size() >> 8));
    f.push_back(static_cast<char>(payload.size() & 0xff));
  } else {
    f.push_back(static_cast<char>(mask_bit | 127));
    for (int k = 7; k >= 0; --k) f.push_back(static_cast<char>((payload.size() >> (8 * k)) & 0xff));
  }
  if (masked) f.append(4, '\0');
  return f + payload;
}

/// Sends a WebSocket upgrade on `s` (with `headers`, each ending in CRLF, after the Host line)
/// and returns the reply's status line and headers.
std::string upgrade(Socket& s, const std::string& path, const std::string& host,
                    const std::string& headers = "") {
  s.send("GET " + path + " HTTP/1.1\r\nHost: " + host + "\r\n" + headers +
         "Upgrade: websocket\r\nConnection: Upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n");
  const std::string reply = s.receive(3000, "\r\n\r\n");
  const std::size_t end = reply.find("\r\n\r\n");
  if (end != std::string::npos) s.leftover = reply.substr(end + 4);
  return reply;
}

/// Opens a WebSocket on `s`; true when the server switched protocols.
bool handshake(Socket& s, const std::string& path = "/ws") {
  return upgrade(s, path, "127.0.0.1").rfind("HTTP/1.1 101", 0) == 0;
}

struct Fixture {
  explicit Fixture(ViewerServerOptions options = {}) {
    options.port = 0;
    std::map<std::string, ServedFile> files;
    files["/"] = {"text/html", "<p>page</p>"};
    files["/viewer.js"] = {"text/javascript", "// script"};
    server = std::make_unique<ViewerServer>(options, files, [this](const std::string& text) {
      std::lock_guard<std::mutex> lock(mutex);
      messages.push_back(text);
    });
  }
  std::size_t message_count() {
    std::lock_guard<std::mutex> lock(mutex);
    return messages.size();
  }
  template <typename P>
  bool wait_for(P predicate, int timeout_ms = 5000) {
    const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
    while (Clock::now() < end) {
      if (predicate()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return predicate();
  }
  std::unique_ptr<ViewerServer> server;
  std::mutex mutex;
  std::vector<std::string> messages;
};

TEST(ViewerServer, ServesItsFilesAndNothingElse) {
  Fixture f;
  const int port = f.server->port();
  EXPECT_NE(get(port, "GET / HTTP/1.1").find("<p>page</p>"), std::string::npos);
  EXPECT_EQ(get(port, "GET /viewer.js?v=1 HTTP/1.1").rfind("HTTP/1.1 200", 0), 0u);
  EXPECT_EQ(get(port, "GET /nothing HTTP/1.1").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(port, "GET /../../etc/passwd HTTP/1.1").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(port, "GET /%2e%2e/%2e%2e/etc/passwd HTTP/1.1").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(port, "GET ../viewer.js HTTP/1.1").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(port, "POST / HTTP/1.1").rfind("HTTP/1.1 405", 0), 0u);
  EXPECT_EQ(get(port, "DELETE /viewer.js HTTP/1.1").rfind("HTTP/1.1 405", 0), 0u);
  const std::string head = get(port, "HEAD / HTTP/1.1");
  EXPECT_EQ(head.rfind("HTTP/1.1 200", 0), 0u);
  EXPECT_EQ(head.find("<p>page</p>"), std::string::npos);
}

TEST(ViewerServer, MalformedAndOversizedRequestsGetAnErrorOrAClose) {
  Fixture f;
  const int port = f.server->port();
  {
    Socket s(port);
    s.send("THIS IS NOT HTTP\r\n\r\n");
    const std::string reply = s.receive(3000);
    EXPECT_EQ(reply.rfind("HTTP/1.1 400", 0), 0u) << reply;
  }
  {
    Socket s(port);
    s.send("GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(64 * 1024, 'a') + "\r\n\r\n");
    const std::string reply = s.receive(3000);
    EXPECT_TRUE(reply.rfind("HTTP/1.1 400", 0) == 0 || s.closed()) << reply.substr(0, 80);
  }
  {
    Socket s(port);  // a body larger than the limit
    s.send("GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n" +
           std::string(100000, 'b'));
    const std::string reply = s.receive(3000);
    EXPECT_TRUE(reply.rfind("HTTP/1.1 400", 0) == 0 || s.closed()) << reply.substr(0, 80);
  }
  {
    Socket s(port);  // an upgrade to another path
    EXPECT_FALSE(handshake(s, "/other"));
  }
  // The server still answers.
  EXPECT_NE(get(port, "GET / HTTP/1.1").find("<p>page</p>"), std::string::npos);
}

TEST(ViewerServer, AClientThatSendsNothingIsClosedAfterTheTimeout) {
  ViewerServerOptions options;
  options.handshake_timeout_s = 0.5;
  Fixture f(options);
  Socket s(f.server->port());
  s.send("GET / HTTP/1.1\r\n");  // and never the rest
  s.receive(3000);
  EXPECT_TRUE(s.closed());
}

TEST(ViewerServer, WebSocketMessagesReachTheHandler) {
  Fixture f;
  Socket s(f.server->port());
  ASSERT_TRUE(handshake(s));
  s.send(client_frame(0x1, R"({"cmd": "pause"})"));
  ASSERT_TRUE(f.wait_for([&] { return f.message_count() == 1; }));
  EXPECT_EQ(f.messages[0], R"({"cmd": "pause"})");
}

TEST(ViewerServer, MalformedWebSocketFramesCloseTheConnection) {
  Fixture f;
  const int port = f.server->port();
  {
    Socket s(port);  // a client frame must be masked
    ASSERT_TRUE(handshake(s));
    s.send(client_frame(0x1, "unmasked", false));
    s.receive(3000);
    EXPECT_TRUE(s.closed());
  }
  {
    Socket s(port);  // a reserved opcode
    ASSERT_TRUE(handshake(s));
    s.send(client_frame(0x3, "reserved"));
    s.receive(3000);
    EXPECT_TRUE(s.closed());
  }
  {
    Socket s(port);  // random bytes
    ASSERT_TRUE(handshake(s));
    s.send(std::string("\xff\xff\xff\xff\x00\x01garbage", 14));
    s.receive(3000);
    EXPECT_TRUE(s.closed());
  }
  {
    Socket s(port);  // larger than max_message_bytes
    ASSERT_TRUE(handshake(s));
    s.send(client_frame(0x1, std::string(100000, 'x')));
    s.receive(3000);
    EXPECT_TRUE(s.closed());
  }
  EXPECT_EQ(f.message_count(), 0u);
  EXPECT_TRUE(f.wait_for([&] { return f.server->stats().clients == 0; }));
  // Still serving.
  Socket good(port);
  ASSERT_TRUE(handshake(good));
  good.send(client_frame(0x1, "ok"));
  EXPECT_TRUE(f.wait_for([&] { return f.message_count() == 1; }));
}

TEST(ViewerServer, SeveralClientsGetTheNewestMessage) {
  Fixture f;
  const int port = f.server->port();
  std::vector<std::unique_ptr<Socket>> clients;
  for (int k = 0; k < 3; ++k) {
    clients.push_back(std::make_unique<Socket>(port));
    ASSERT_TRUE(handshake(*clients.back()));
  }
  ASSERT_TRUE(f.wait_for([&] { return f.server->stats().clients == 3; }));
  f.server->publish(ViewerChannel::kStats, "hello-all", false);
  for (auto& c : clients)
    EXPECT_NE(c->receive(3000, "hello-all").find("hello-all"), std::string::npos);
  // A client that connects later gets the newest message of the channel at once.
  Socket late(port);
  ASSERT_TRUE(handshake(late));
  EXPECT_NE(late.receive(3000, "hello-all").find("hello-all"), std::string::npos);
}

TEST(ViewerServer, AClientThatNeverReadsNeitherBlocksPublishNorOthers) {
  ViewerServerOptions options;
  options.write_timeout_s = 0.5;
  Fixture f(options);
  const int port = f.server->port();
  Socket stalled(port, 4096);  // connects, then never reads
  ASSERT_TRUE(handshake(stalled));
  Socket reader(port);
  ASSERT_TRUE(handshake(reader));
  ASSERT_TRUE(f.wait_for([&] { return f.server->stats().clients == 2; }));
  const std::string big(1 << 20, 'm');
  double slowest_ms = 0.0;
  for (int k = 0; k < 60; ++k) {
    const auto start = Clock::now();
    f.server->publish(ViewerChannel::kFrame, big, true);
    slowest_ms = std::max(slowest_ms,
                          std::chrono::duration<double, std::milli>(Clock::now() - start).count());
    reader.receive(20);  // the good client keeps reading
  }
  EXPECT_LT(slowest_ms, 100.0);  // publish never waits for a client
  EXPECT_TRUE(f.wait_for([&] { return f.server->stats().clients_dropped >= 1; }));
  EXPECT_GT(f.server->stats().messages_dropped, 0u);  // newest wins
  f.server->publish(ViewerChannel::kStats, "still-here", false);
  EXPECT_NE(reader.receive(5000, "still-here").find("still-here"), std::string::npos);
}

TEST(ViewerServer, AForeignOriginOrHostIsRefused) {
  // A page of another site may open a WebSocket to 127.0.0.1 (browsers apply no same-origin
  // policy to them), and DNS rebinding reaches the HTTP side under a name of its own.
  Fixture f;
  const int port = f.server->port();
  const std::string own = "127.0.0.1:" + std::to_string(port);
  {
    Socket s(port);
    EXPECT_EQ(upgrade(s, "/ws", own, "Origin: http://evil.example\r\n").rfind("HTTP/1.1 403", 0),
              0u);
  }
  {
    Socket s(port);  // the same host on another port is another origin
    EXPECT_EQ(upgrade(s, "/ws", own, "Origin: http://127.0.0.1:9999\r\n").rfind("HTTP/1.1 403", 0),
              0u);
  }
  {
    Socket s(port);
    EXPECT_EQ(upgrade(s, "/ws", "evil.example:" + std::to_string(port)).rfind("HTTP/1.1 403", 0),
              0u);
  }
  {
    Socket s(port);
    s.send("GET / HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n");
    const std::string reply = s.receive(3000);
    EXPECT_EQ(reply.rfind("HTTP/1.1 403", 0), 0u) << reply;
    EXPECT_EQ(reply.find("<p>page</p>"), std::string::npos);
  }
  {
    Socket s(port);  // HTTP/1.0 without a Host: a browser always sends one
    s.send("GET / HTTP/1.0\r\n\r\n");
    const std::string reply = s.receive(3000);
    EXPECT_EQ(reply.rfind("HTTP/1.0 403", 0), 0u) << reply;
  }
  EXPECT_EQ(f.server->stats().refused, 5u);
  EXPECT_EQ(f.server->stats().connections, 0u);
  // The viewer's own page: its origin, under the names of this machine.
  for (const std::string& host : {own, "localhost:" + std::to_string(port)}) {
    Socket s(port);
    EXPECT_EQ(upgrade(s, "/ws", host, "Origin: http://" + host + "\r\n").rfind("HTTP/1.1 101", 0),
              0u)
        << host;
  }
  Socket no_origin(port);  // a client that is not a browser sends none
  EXPECT_TRUE(handshake(no_origin));
}

TEST(ViewerServer, HostNamesAllowedByTheBoundAddress) {
  EXPECT_TRUE(viewer_host_allowed("127.0.0.1:8765", "127.0.0.1"));
  EXPECT_TRUE(viewer_host_allowed("LOCALHOST:8765", "127.0.0.1"));
  EXPECT_TRUE(viewer_host_allowed("[::1]:8765", "::1"));
  EXPECT_TRUE(viewer_host_allowed("192.168.1.5:8765", "192.168.1.5"));
  EXPECT_FALSE(viewer_host_allowed("192.168.1.6:8765", "192.168.1.5"));
  EXPECT_FALSE(viewer_host_allowed("", "127.0.0.1"));
  EXPECT_FALSE(viewer_host_allowed("robot.example:8765", "127.0.0.1"));
  // Bound to every address: any IP literal (a rebound name is never one), no other name.
  EXPECT_TRUE(viewer_host_allowed("10.0.0.7:8765", "0.0.0.0"));
  EXPECT_TRUE(viewer_host_allowed("[fe80::1]:8765", "::"));
  EXPECT_FALSE(viewer_host_allowed("evil.example:8765", "0.0.0.0"));
  EXPECT_TRUE(viewer_origin_allowed("", "127.0.0.1:8765"));
  EXPECT_TRUE(viewer_origin_allowed("http://127.0.0.1:8765", "127.0.0.1:8765"));
  EXPECT_FALSE(viewer_origin_allowed("https://127.0.0.1:8765", "127.0.0.1:8765"));
  EXPECT_FALSE(viewer_origin_allowed("null", "127.0.0.1:8765"));
}

TEST(ViewerServer, ConnectionsBeyondTheLimitsAreRefused) {
  ViewerServerOptions options;
  options.max_clients = 2;
  options.max_connections = 4;
  Fixture f(options);
  const int port = f.server->port();
  // Handshakes in progress count against max_clients: two upgrades sent, a third refused
  // before either has finished being counted as a client.
  std::vector<std::unique_ptr<Socket>> clients;
  for (int k = 0; k < 2; ++k) {
    clients.push_back(std::make_unique<Socket>(port));
    ASSERT_TRUE(handshake(*clients.back()));
  }
  {
    Socket third(port);
    EXPECT_EQ(upgrade(third, "/ws", "127.0.0.1").rfind("HTTP/1.1 503", 0), 0u);
  }
  // Plain connections that send nothing count against max_connections: with 2 WebSockets and
  // 2 idle connections open, the next one is closed at once.
  Socket idle1(port), idle2(port);
  ASSERT_TRUE(f.wait_for([&] {
    Socket probe(port);
    probe.receive(500);
    return probe.closed() && f.server->stats().over_limit >= 2;
  }));
  clients.clear();  // the WebSockets go: room again
  ASSERT_TRUE(f.wait_for([&] { return f.server->stats().clients == 0; }));
  EXPECT_NE(get(port, "GET / HTTP/1.1").find("<p>page</p>"), std::string::npos);
}

TEST(ViewerServer, APortInUseOrABadAddressIsAnInputError) {
  Fixture f;
  ViewerServerOptions same;
  same.port = f.server->port();
  try {
    ViewerServer second(same, {}, nullptr);
    FAIL() << "a second server on the same port";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1:"), std::string::npos)
        << e.what();
  }
  ViewerServerOptions bad;
  bad.bind = "not-an-address";
  EXPECT_THROW(ViewerServer(bad, {}, nullptr), InputError);
  bad.bind = "127.0.0.1";
  bad.port = 70000;
  EXPECT_THROW(ViewerServer(bad, {}, nullptr), InputError);
}

/// A snapshot with an odd number of cells (the voxels after them start unaligned without
/// padding), a grid frame turned and moved, and `voxels` voxels of distinct centres and colours.
mapping::OccupancySnapshot test_snapshot(std::size_t voxels) {
  mapping::OccupancySnapshot s;
  s.version = 7;
  s.grid.width = 5;
  s.grid.height = 3;
  s.grid.resolution = 0.05;
  s.grid.T_world_grid.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  s.grid.T_world_grid.topRightCorner<3, 1>() = Eigen::Vector3d(-1.25, 0.5, 2.0);
  for (int i = 0; i < 15; ++i)
    s.grid.cells.push_back(i % 3 == 0   ? mapping::OccupancyGrid::kOccupied
                           : i % 3 == 1 ? mapping::OccupancyGrid::kFree
                                        : mapping::OccupancyGrid::kUnknown);
  for (std::size_t i = 0; i < voxels; ++i) {
    mapping::OccupiedVoxel v;
    v.centre = Eigen::Vector3d(0.05 * static_cast<double>(i), -0.5, 1.0 + 0.001 * i);
    v.size = i % 2 == 0 ? 0.05 : 0.1;
    v.rgb = {static_cast<std::uint8_t>(i % 256), static_cast<std::uint8_t>(7 * i % 256), 200};
    s.voxels.push_back(v);
  }
  return s;
}

/// The occupancy message read as the page reads it; every array must start 4-byte aligned.
struct DecodedOccupancy {
  nlohmann::json header;
  std::vector<float> T, centres, sizes;
  std::vector<std::int8_t> cells;
  std::vector<std::uint8_t> rgb;
  std::size_t end = 0;  ///< the offset after the last array, padded
};

template <typename T>
std::vector<T> take(const std::string& bytes, std::size_t& offset, std::size_t count) {
  offset = (offset + 3) / 4 * 4;
  EXPECT_LE(offset + count * sizeof(T), bytes.size());
  std::vector<T> out(count);
  if (offset + count * sizeof(T) <= bytes.size())
    std::memcpy(out.data(), bytes.data() + offset, count * sizeof(T));
  offset += count * sizeof(T);
  return out;
}

DecodedOccupancy decode_occupancy(const std::string& bytes) {
  DecodedOccupancy d;
  EXPECT_GE(bytes.size(), 8u);
  EXPECT_EQ(bytes.substr(0, 4), std::string("\x03\0\0\0", 4));
  std::uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 4, 4);
  d.header = nlohmann::json::parse(bytes.substr(8, length));
  std::size_t offset = 8 + length;
  const std::size_t cells =
      d.header["width"].get<std::size_t>() * d.header["height"].get<std::size_t>();
  const std::size_t n = d.header["voxels"].get<std::size_t>();
  d.T = take<float>(bytes, offset, 16);
  d.cells = take<std::int8_t>(bytes, offset, cells);
  d.centres = take<float>(bytes, offset, 3 * n);
  d.sizes = take<float>(bytes, offset, n);
  d.rgb = take<std::uint8_t>(bytes, offset, 3 * n);
  d.end = (offset + 3) / 4 * 4;
  return d;
}

TEST(ViewerOccupancy, TheMessageDecodesToTheSnapshotsGridAndVoxels) {
  const mapping::OccupancySnapshot s = test_snapshot(10);
  const std::string bytes = occupancy_message(s, 1000);
  EXPECT_EQ(bytes.size() % 4, 0u);
  const DecodedOccupancy d = decode_occupancy(bytes);
  EXPECT_EQ(d.end, bytes.size());  // nothing after the last array but its padding
  EXPECT_EQ(d.header["version"], 7);
  EXPECT_EQ(d.header["width"], 5);
  EXPECT_EQ(d.header["height"], 3);
  EXPECT_DOUBLE_EQ(d.header["resolution"].get<double>(), 0.05);
  EXPECT_EQ(d.header["voxels"], 10);
  EXPECT_EQ(d.header["voxels_in_map"], 10);
  for (int c = 0; c < 4; ++c)  // column-major
    for (int r = 0; r < 4; ++r)
      EXPECT_FLOAT_EQ(d.T[4 * c + r], static_cast<float>(s.grid.T_world_grid(r, c)));
  EXPECT_EQ(d.cells, s.grid.cells);
  for (std::size_t i = 0; i < 10; ++i) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_FLOAT_EQ(d.centres[3 * i + a], static_cast<float>(s.voxels[i].centre[a]));
      EXPECT_EQ(d.rgb[3 * i + a], s.voxels[i].rgb[a]);
    }
    EXPECT_FLOAT_EQ(d.sizes[i], static_cast<float>(s.voxels[i].size));
  }
}

TEST(ViewerOccupancy, MoreVoxelsThanTheLimitAreThinnedEvenly) {
  const mapping::OccupancySnapshot s = test_snapshot(2500);
  const std::string bytes = occupancy_message(s, 1000);
  const DecodedOccupancy d = decode_occupancy(bytes);
  EXPECT_EQ(d.end, bytes.size());
  EXPECT_EQ(d.header["voxels"], 1000);
  EXPECT_EQ(d.header["voxels_in_map"], 2500);
  ASSERT_EQ(d.sizes.size(), 1000u);
  // Voxel k of the message is voxel k * 2500 / 1000 of the snapshot: spread over all of it.
  for (std::size_t k = 0; k < 1000; ++k) {
    const mapping::OccupiedVoxel& v = s.voxels[k * 5 / 2];
    EXPECT_FLOAT_EQ(d.centres[3 * k], static_cast<float>(v.centre.x())) << k;
    EXPECT_FLOAT_EQ(d.sizes[k], static_cast<float>(v.size)) << k;
    EXPECT_EQ(d.rgb[3 * k + 1], v.rgb[1]) << k;
  }
  EXPECT_GT(d.centres[3 * 999], 0.9f * static_cast<float>(s.voxels.back().centre.x()));
  // An empty map: a grid of no cells and no voxels, still well formed.
  const std::string empty = occupancy_message(mapping::OccupancySnapshot{}, 1000);
  const DecodedOccupancy e = decode_occupancy(empty);
  EXPECT_EQ(e.end, empty.size());
  EXPECT_TRUE(e.cells.empty() && e.sizes.empty());
}

TEST(ViewerOccupancy, TheVoxelLimitIsChecked) {
  ViewerOptions options;
  EXPECT_FALSE(options.check());
  options.max_voxels = 999;
  ASSERT_TRUE(options.check());
  EXPECT_NE(options.check()->find("max_voxels"), std::string::npos);
}

}  // namespace
}  // namespace mcslam::app
