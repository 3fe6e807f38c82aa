#include "mcslam/app/viewer_server.hpp"

#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cctype>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>

#include "mcslam/core/error.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/core/worker.hpp"

namespace mcslam::app {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

struct Message {
  std::string data;
  bool binary = false;
};
using MessagePtr = std::shared_ptr<const Message>;

std::chrono::milliseconds to_ms(double seconds) {
  return std::chrono::milliseconds(static_cast<long long>(seconds * 1000.0));
}

/// The host part of a Host header: "[::1]:8765" -> "::1", "localhost:8765" -> "localhost".
std::string host_name(const std::string& host) {
  if (!host.empty() && host.front() == '[') {
    const std::size_t end = host.find(']');
    return end == std::string::npos ? std::string() : host.substr(1, end - 1);
  }
  const std::size_t colon = host.find(':');
  if (colon != std::string::npos && host.find(':', colon + 1) != std::string::npos)
    return host;  // a bare IPv6 address (not valid in a Host header, judged as it is)
  return host.substr(0, colon);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

bool viewer_host_allowed(const std::string& host, const std::string& bind) {
  const std::string name = lower(host_name(host));
  if (name.empty()) return false;
  if (name == "localhost" || name == "127.0.0.1" || name == "::1" || name == lower(bind))
    return true;
  // Bound to every address: reached by whatever address the machine has. An IP literal cannot
  // be rebound by a foreign DNS name, so any is accepted; names other than localhost are not.
  beast::error_code ec;
  const net::ip::address bound = net::ip::make_address(bind, ec);
  if (ec || !bound.is_unspecified()) return false;
  net::ip::make_address(name, ec);
  return !ec;
}

bool viewer_origin_allowed(const std::string& origin, const std::string& host) {
  return origin.empty() || lower(origin) == "http://" + lower(host);
}

std::optional<std::string> ViewerServerOptions::check() const {
  if (port < 0 || port > 65535) return "port: must be 0..65535, got " + std::to_string(port);
  if (max_message_bytes < 16) return "max_message_bytes: must be at least 16";
  if (max_clients < 1) return "max_clients: must be at least 1";
  if (max_connections < max_clients + 1)
    return "max_connections: must exceed max_clients (a page is loaded beside its WebSocket)";
  if (!(write_timeout_s > 0.0)) return "write_timeout_s: must be positive";
  if (!(handshake_timeout_s > 0.0)) return "handshake_timeout_s: must be positive";
  return std::nullopt;
}

class WsSession;

struct ViewerServer::Impl {
  ViewerServerOptions options;
  std::map<std::string, ServedFile> files;
  MessageHandler on_message;
  // The server thread's counts of its sessions (declared before the io_context, whose
  // destruction may end the last sessions).
  std::size_t open_connections = 0;  // HTTP sessions and WebSockets alive
  std::size_t pending_handshakes = 0;
  net::io_context ioc{1};
  tcp::acceptor acceptor{ioc};
  net::steady_timer watchdog{ioc};
  net::steady_timer accept_backoff{ioc};
  std::chrono::milliseconds backoff{0};
  // Touched on the server's thread only.
  std::set<std::shared_ptr<WsSession>> sessions;
  ThreadFailure failure{"viewer server (mcslam-viewer)"};
  std::array<MessagePtr, kViewerChannels> latest;
  mutable std::mutex stats_mutex;
  ViewerServerStats stats;
  int port = 0;
  std::thread thread;

  void accept();
  void watch();
  void add(const std::shared_ptr<WsSession>& session);
  void remove(const std::shared_ptr<WsSession>& session, bool dropped);
  template <typename F>
  void count(F f) {
    std::lock_guard<std::mutex> lock(stats_mutex);
    f(stats);
  }
};

/// One WebSocket client: the newest message of each channel waits while one is being written.
class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(beast::tcp_stream stream, ViewerServer::Impl& server)
      : ws_(std::move(stream)), server_(server) {
    ++server_.open_connections;
    ++server_.pending_handshakes;
  }
  ~WsSession() {
    --server_.open_connections;
    if (handshaking_) --server_.pending_handshakes;
  }

  void accept(http::request<http::string_body> request) {
    request_ = std::move(request);  // kept for as long as the handshake may read it
    beast::get_lowest_layer(ws_).expires_never();
    websocket::stream_base::timeout timeout{};
    timeout.handshake_timeout = to_ms(server_.options.handshake_timeout_s);
    timeout.idle_timeout = to_ms(3.0 * server_.options.handshake_timeout_s);
    timeout.keep_alive_pings = true;  // a client that answers no ping is closed
    ws_.set_option(timeout);
    ws_.read_message_max(server_.options.max_message_bytes);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& response) { response.set(http::field::server, "mcslam"); }));
    ws_.async_accept(request_, [self = shared_from_this()](beast::error_code ec) {
      self->handshaking_ = false;
      --self->server_.pending_handshakes;
      if (ec) return;  // a failed handshake: the connection goes
      self->server_.add(self);
      self->read();
    });
  }

  void offer(ViewerChannel channel, const MessagePtr& message) {
    MessagePtr& slot = pending_[static_cast<std::size_t>(channel)];
    if (slot) server_.count([](ViewerServerStats& s) { ++s.messages_dropped; });
    slot = message;
    if (!writing_) write_next();
  }

  bool stalled(Clock::time_point now) const {
    return writing_ && now - write_started_ > to_ms(server_.options.write_timeout_s);
  }

  /// Closes the socket at once: pending operations end with an error.
  void drop() {
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(ws_).socket().close(ec);
  }

 private:
  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        // A malformed or oversized message is a protocol error: Beast has sent the close.
        const bool bad = ec != websocket::error::closed && ec != net::error::operation_aborted &&
                         ec != net::error::eof && ec != net::error::connection_reset;
        self->server_.remove(self, bad);
        return;
      }
      if (self->ws_.got_text() && self->server_.on_message)
        self->server_.on_message(beast::buffers_to_string(self->buffer_.data()));
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }

  void write_next() {
    for (MessagePtr& slot : pending_) {
      if (!slot) continue;
      in_flight_ = std::move(slot);
      slot.reset();
      writing_ = true;
      write_started_ = Clock::now();
      ws_.binary(in_flight_->binary);
      ws_.async_write(net::buffer(in_flight_->data),
                      [self = shared_from_this()](beast::error_code ec, std::size_t) {
                        self->writing_ = false;
                        self->in_flight_.reset();
                        if (ec) {
                          self->server_.remove(self, false);
                          return;
                        }
                        self->server_.count([](ViewerServerStats& s) { ++s.messages_sent; });
                        self->write_next();
                      });
      return;
    }
  }

  websocket::stream<beast::tcp_stream> ws_;
  ViewerServer::Impl& server_;
  http::request<http::string_body> request_;
  beast::flat_buffer buffer_;
  std::array<MessagePtr, kViewerChannels> pending_;
  MessagePtr in_flight_;
  bool writing_ = false;
  bool handshaking_ = true;
  Clock::time_point write_started_;
};

/// One HTTP connection: fixed files, or the upgrade to the WebSocket at /ws.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, ViewerServer::Impl& server)
      : stream_(std::move(socket)), server_(server) {
    ++server_.open_connections;
  }
  ~HttpSession() { --server_.open_connections; }

  void read() {
    parser_.emplace();
    parser_->header_limit(8 * 1024);
    parser_->body_limit(server_.options.max_message_bytes);
    stream_.expires_after(to_ms(server_.options.handshake_timeout_s));
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

 private:
  void on_read(beast::error_code ec) {
    if (ec == http::error::end_of_stream || ec == beast::error::timeout ||
        ec == net::error::operation_aborted || ec == net::error::connection_reset ||
        ec == net::error::eof) {
      close();
      return;
    }
    if (ec) {  // a malformed or oversized request
      respond(http::status::bad_request, "bad request: " + ec.message() + "\n", "text/plain", 11,
              false, false);
      return;
    }
    http::request<http::string_body> request = parser_->release();
    std::string target(request.target());
    target = target.substr(0, target.find('?'));
    const std::string host(request[http::field::host]);
    if (!viewer_host_allowed(host, server_.options.bind)) {
      server_.count([](ViewerServerStats& s) { ++s.refused; });
      respond(http::status::forbidden, "forbidden: this viewer answers to localhost only\n",
              "text/plain", request.version(), false, false);
      return;
    }
    if (websocket::is_upgrade(request)) {
      if (target != "/ws") {
        respond(http::status::not_found, "not found\n", "text/plain", request.version(), false,
                false);
      } else if (!viewer_origin_allowed(std::string(request[http::field::origin]), host)) {
        server_.count([](ViewerServerStats& s) { ++s.refused; });
        respond(http::status::forbidden, "forbidden: a page of another origin\n", "text/plain",
                request.version(), false, false);
      } else if (server_.sessions.size() + server_.pending_handshakes >=
                 server_.options.max_clients) {
        server_.count([](ViewerServerStats& s) { ++s.over_limit; });
        respond(http::status::service_unavailable, "too many viewers\n", "text/plain",
                request.version(), false, false);
      } else {
        std::make_shared<WsSession>(std::move(stream_), server_)->accept(std::move(request));
      }
      return;
    }
    const bool head = request.method() == http::verb::head;
    if (request.method() != http::verb::get && !head) {
      respond(http::status::method_not_allowed, "method not allowed\n", "text/plain",
              request.version(), false, false);
      return;
    }
    const auto file = server_.files.find(target);
    if (file == server_.files.end()) {
      respond(http::status::not_found, "not found\n", "text/plain", request.version(),
              request.keep_alive(), head);
      return;
    }
    respond(http::status::ok, file->second.body, file->second.content_type, request.version(),
            request.keep_alive(), head);
  }

  void respond(http::status status, const std::string& body, const std::string& type,
               unsigned version, bool keep_alive, bool head) {
    auto response = std::make_shared<http::response<http::string_body>>(status, version);
    response->set(http::field::server, "mcslam");
    response->set(http::field::content_type, type);
    response->set(http::field::cache_control, "no-store");
    response->set("X-Content-Type-Options", "nosniff");
    response->set("Content-Security-Policy",
                  "default-src 'self'; connect-src 'self'; img-src 'self' blob: data:; "
                  "style-src 'self' 'unsafe-inline'");
    response->keep_alive(keep_alive);
    response->body() = body;
    response->prepare_payload();
    if (head) response->body().clear();  // Content-Length stays that of the body
    stream_.expires_after(to_ms(server_.options.write_timeout_s));
    http::async_write(stream_, *response,
                      [self = shared_from_this(), response](beast::error_code ec, std::size_t) {
                        if (ec || !response->keep_alive()) {
                          self->close();
                          return;
                        }
                        self->read();
                      });
  }

  void close() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
    stream_.socket().close(ec);
  }

  beast::tcp_stream stream_;
  ViewerServer::Impl& server_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

void ViewerServer::Impl::accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == net::error::operation_aborted || !acceptor.is_open()) return;
    if (ec) {
      // A persistent error (EMFILE: no file descriptor left) would fail again at once: wait,
      // 10 ms doubling to 1 s while it lasts, before accepting again.
      count([](ViewerServerStats& s) { ++s.accept_errors; });
      backoff = std::min(std::chrono::milliseconds(1000),
                         std::max(std::chrono::milliseconds(10), 2 * backoff));
      accept_backoff.expires_after(backoff);
      accept_backoff.async_wait([this](beast::error_code wait_ec) {
        if (!wait_ec) accept();
      });
      return;
    }
    backoff = std::chrono::milliseconds(0);
    if (open_connections >= options.max_connections) {
      count([](ViewerServerStats& s) { ++s.over_limit; });
      beast::error_code close_ec;
      socket.close(close_ec);
    } else {
      std::make_shared<HttpSession>(std::move(socket), *this)->read();
    }
    accept();
  });
}

void ViewerServer::Impl::watch() {
  watchdog.expires_after(std::chrono::milliseconds(250));
  watchdog.async_wait([this](beast::error_code ec) {
    if (ec) return;
    const Clock::time_point now = Clock::now();
    const std::vector<std::shared_ptr<WsSession>> all(sessions.begin(), sessions.end());
    for (const auto& session : all)
      if (session->stalled(now)) {
        session->drop();
        remove(session, true);
      }
    watch();
  });
}

void ViewerServer::Impl::add(const std::shared_ptr<WsSession>& session) {
  sessions.insert(session);
  count([this](ViewerServerStats& s) {
    ++s.connections;
    s.clients = sessions.size();
    s.clients_max = std::max(s.clients_max, s.clients);
  });
  for (std::size_t c = 0; c < kViewerChannels; ++c)
    if (latest[c]) session->offer(static_cast<ViewerChannel>(c), latest[c]);
}

void ViewerServer::Impl::remove(const std::shared_ptr<WsSession>& session, bool dropped) {
  if (sessions.erase(session) == 0) return;
  count([&](ViewerServerStats& s) {
    s.clients = sessions.size();
    s.clients_dropped += dropped ? 1 : 0;
  });
}

ViewerServer::ViewerServer(const ViewerServerOptions& options,
                           std::map<std::string, ServedFile> files, MessageHandler on_message)
    : impl_(std::make_unique<Impl>()) {
  if (auto e = options.check()) throw InputError("viewer: " + *e);
  impl_->options = options;
  impl_->files = std::move(files);
  impl_->on_message = std::move(on_message);
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(options.bind, ec);
  if (ec) throw InputError("--viewer-bind: '" + options.bind + "' is not an IP address");
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
  const std::string where = options.bind + ":" + std::to_string(options.port);
  tcp::acceptor& acceptor = impl_->acceptor;
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) throw InputError("--viewer: cannot listen on " + where + ": " + ec.message());
  impl_->port = acceptor.local_endpoint().port();
  impl_->accept();
  impl_->watch();
  impl_->thread = std::thread([impl = impl_.get()] {
    set_current_thread_name("mcslam-viewer");
    try {
      impl->ioc.run();
    } catch (...) {
      // A handler threw: the server stops serving; the run goes on and reports it.
      impl->failure.set(std::current_exception());
    }
  });
}

ViewerServer::~ViewerServer() {
  net::post(impl_->ioc, [impl = impl_.get()] {
    beast::error_code ec;
    impl->acceptor.close(ec);
    impl->watchdog.cancel();
    impl->accept_backoff.cancel();
    for (const auto& session : impl->sessions) session->drop();
    impl->sessions.clear();
    impl->ioc.stop();
  });
  if (impl_->thread.joinable()) impl_->thread.join();
}

int ViewerServer::port() const { return impl_->port; }

void ViewerServer::publish(ViewerChannel channel, std::string payload, bool binary) {
  if (impl_->failure.failed()) return;  // nothing runs the posted work any more
  auto message = std::make_shared<const Message>(Message{std::move(payload), binary});
  net::post(impl_->ioc, [impl = impl_.get(), channel, message] {
    impl->latest[static_cast<std::size_t>(channel)] = message;
    for (const auto& session : impl->sessions) session->offer(channel, message);
  });
}

std::string ViewerServer::failure() const { return impl_->failure.message(); }

ViewerServerStats ViewerServer::stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

}  // namespace mcslam::app
