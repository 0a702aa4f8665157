// The viewer's HTTP + WebSocket side on CivetWeb (Debian libcivetweb-dev 1.15): the bundled
// page from a directory, the scene description and model data from memory, and the frames to
// every connected page over one WebSocket each (view_frame.hpp). CivetWeb runs its own worker
// threads; broadcast() may be called from any one other thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"

struct mg_context;
struct mg_connection;

namespace trainer::viewer {

struct WebServerOptions {
  std::string address = "127.0.0.1";  // listen address; 0.0.0.0 for other machines on the LAN
  std::uint16_t port = 8080;          // 0: any free port (see WebServer::port())
  std::filesystem::path web_root;     // the bundled page: index.html, viewer.js
};

struct WebContent {
  std::string scene_json;
  std::vector<std::vector<std::byte>> model_blobs;  // served as /model/<i>.bin
};

class WebServer {
 public:
  static core::Expected<std::unique_ptr<WebServer>> start(const WebServerOptions& options,
                                                          WebContent content);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  std::uint16_t port() const noexcept { return port_; }
  // Sends one binary frame to every page; stamps its "handed to the WebSocket" time first.
  void broadcast_frame(std::vector<std::byte>& frame);
  void broadcast_text(const std::string& text);
  std::size_t client_count();
  std::uint64_t frames_sent() const noexcept { return frames_sent_.load(); }
  // The last statistics JSON a page sent (its frame rate and latencies), "" before any.
  std::string last_page_stats();
  // The page's playback requests ({"type":"playback",...}) since the last call, in order.
  std::vector<std::string> take_controls();

  // CivetWeb callbacks (C linkage trampolines call these).
  int handle_request(mg_connection* connection);
  void on_ready(mg_connection* connection);
  void on_text(const char* data, std::size_t length);
  void on_close(const mg_connection* connection);

 private:
  WebServer() = default;
  mg_context* context_ = nullptr;
  std::uint16_t port_ = 0;
  WebContent content_;
  std::mutex mutex_;  // clients_, page_stats_, controls_
  std::vector<mg_connection*> clients_;
  std::string page_stats_;
  std::vector<std::string> controls_;
  std::atomic<std::uint64_t> frames_sent_{0};
};

}  // namespace trainer::viewer
