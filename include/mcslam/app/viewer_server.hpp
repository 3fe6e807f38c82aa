#pragma once
// The live viewer's HTTP and WebSocket server (Boost.Beast, on a thread of its own).
//
// It serves a fixed set of pages (any other path is 404, any method but GET and HEAD 405) and
// one WebSocket endpoint, /ws, to which it pushes messages on a few channels. Each channel keeps
// only its newest message: a client that is still writing the one before gets the newest when
// it is ready, and what it missed is dropped. publish() never waits for a client; a client whose
// write has stalled for write_timeout_s is disconnected. Text messages from clients (at most
// max_message_bytes; a longer one closes the connection) go to the message handler.
//
// Who may connect. Browsers let any web page open a WebSocket to 127.0.0.1, and DNS rebinding
// lets a page reach the HTTP side under a name of its own. So a request is answered only when
// its Host is this machine's loopback name or address, the bound address, or (bound to every
// address) any IP literal; and a WebSocket upgrade only when it carries no Origin or the origin
// of the viewer's own page (http://<Host>). Anything else gets 403.

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>

namespace mcslam::app {

/// Whether a request's Host header names this server (see the header comment); `bind` is the
/// address listened on. Exposed for tests.
bool viewer_host_allowed(const std::string& host, const std::string& bind);
/// Whether a WebSocket upgrade's Origin (absent: empty) is the viewer's own page for `host`.
bool viewer_origin_allowed(const std::string& origin, const std::string& host);

struct ViewerServerOptions {
  /// The address to listen on: loopback by default; anything else exposes the run.
  std::string bind = "127.0.0.1";
  /// The TCP port (0: any free port, see ViewerServer::port()).
  int port = 8765;
  std::size_t max_message_bytes = 4096;  ///< from a client
  std::size_t max_clients = 16;          ///< WebSocket clients, handshakes in progress included
  /// Open TCP connections of any kind (HTTP requests, handshakes, WebSockets); one more is
  /// closed as soon as it is accepted.
  std::size_t max_connections = 64;
  double write_timeout_s = 5.0;       ///< a client that takes longer to take a message is dropped
  double handshake_timeout_s = 10.0;  ///< for the HTTP request and the WebSocket handshake
  std::optional<std::string> check() const;
};

/// One file the server serves at a fixed path.
struct ServedFile {
  std::string content_type;
  std::string body;
};

/// The channels of the WebSocket (each keeps only its newest message).
enum class ViewerChannel { kHello = 0, kStats = 1, kMap = 2, kFrame = 3, kOccupancy = 4 };
inline constexpr std::size_t kViewerChannels = 5;

struct ViewerServerStats {
  std::size_t clients = 0;           ///< connected now
  std::size_t clients_max = 0;       ///< at most at once
  std::size_t connections = 0;       ///< WebSocket connections accepted
  std::size_t messages_sent = 0;     ///< to all clients
  std::size_t messages_dropped = 0;  ///< replaced by a newer one before a client took them
  std::size_t clients_dropped = 0;   ///< disconnected for a stalled write or a bad message
  std::size_t refused = 0;           ///< requests answered 403 (foreign Host or Origin)
  std::size_t over_limit = 0;        ///< connections closed or answered 503 for a limit
  std::size_t accept_errors = 0;     ///< failed accepts (each followed by a back-off)
};

class ViewerServer {
 public:
  using MessageHandler = std::function<void(const std::string& text)>;
  /// Listens at once; throws InputError when the options are invalid, the address cannot be
  /// parsed or the port cannot be bound (e.g. in use). `on_message` runs on the server's thread
  /// and must return quickly.
  ViewerServer(const ViewerServerOptions& options, std::map<std::string, ServedFile> files,
               MessageHandler on_message);
  /// Closes every connection and joins the thread.
  ~ViewerServer();
  ViewerServer(const ViewerServer&) = delete;
  ViewerServer& operator=(const ViewerServer&) = delete;

  /// The port listened on.
  int port() const;
  /// Sends `payload` to every client on `channel` (newest wins); new clients get the newest
  /// message of each channel when they connect. Thread-safe; never blocks on a client.
  void publish(ViewerChannel channel, std::string payload, bool binary);
  ViewerServerStats stats() const;
  /// The server thread's failure ("" while it runs): an exception out of a handler stops it.
  std::string failure() const;

  struct Impl;  // the server's internals (viewer_server.cpp)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace mcslam::app
