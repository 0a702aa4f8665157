#include "web_server.hpp"

#include <algorithm>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <civetweb.h>

#include "view_frame.hpp"

namespace trainer::viewer {

namespace {

WebServer* server_of(const mg_connection* connection) {
  return static_cast<WebServer*>(mg_get_user_data(mg_get_context(connection)));
}

extern "C" int viewer_request_trampoline(mg_connection* connection, void* /*cbdata*/) {
  return server_of(connection)->handle_request(connection);
}
extern "C" int viewer_ws_connect_trampoline(const mg_connection* /*connection*/, void* /*cbdata*/) {
  return 0;  // accept
}
extern "C" void viewer_ws_ready_trampoline(mg_connection* connection, void* /*cbdata*/) {
  server_of(connection)->on_ready(connection);
}
extern "C" int viewer_ws_data_trampoline(mg_connection* connection, int bits, char* data,
                                         std::size_t length, void* /*cbdata*/) {
  const int opcode = bits & 0x0F;
  if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
  if (opcode == MG_WEBSOCKET_OPCODE_TEXT) server_of(connection)->on_text(data, length);
  return 1;
}
extern "C" void viewer_ws_close_trampoline(const mg_connection* connection, void* /*cbdata*/) {
  server_of(connection)->on_close(connection);
}

}  // namespace

core::Expected<std::unique_ptr<WebServer>> WebServer::start(const WebServerOptions& options,
                                                            WebContent content) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(options.web_root / "index.html", error)) {
    return core::make_error(
        "viewer: no page in " + options.web_root.string() +
        " (index.html missing: build the 'viewer_page' target, or pass --web DIR)");
  }
  std::unique_ptr<WebServer> server(new WebServer());
  server->content_ = std::move(content);
  mg_init_library(0);
  const std::string ports = options.address + ":" + std::to_string(options.port);
  const std::string root = options.web_root.string();
  const char* settings[] = {"listening_ports",
                            ports.c_str(),
                            "document_root",
                            root.c_str(),
                            "num_threads",
                            "8",
                            "websocket_timeout_ms",
                            "3600000",
                            "enable_directory_listing",
                            "no",
                            nullptr};
  mg_callbacks callbacks{};
  mg_init_data init{};
  init.callbacks = &callbacks;
  init.user_data = server.get();
  init.configuration_options = settings;
  char text[256] = {};
  unsigned code = 0;
  mg_error_data errors{};
  errors.code = &code;
  errors.text = text;
  errors.text_buffer_size = sizeof text;
  server->context_ = mg_start2(&init, &errors);
  if (server->context_ == nullptr) {
    return core::make_error("viewer: cannot serve HTTP on " + ports + ": " + text);
  }
  mg_set_request_handler(server->context_, "/scene.json", viewer_request_trampoline, nullptr);
  mg_set_request_handler(server->context_, "/model/", viewer_request_trampoline, nullptr);
  mg_set_websocket_handler(server->context_, "/ws", viewer_ws_connect_trampoline,
                           viewer_ws_ready_trampoline, viewer_ws_data_trampoline,
                           viewer_ws_close_trampoline, nullptr);
  mg_server_port bound[4] = {};
  if (mg_get_server_ports(server->context_, 4, bound) > 0) {
    server->port_ = static_cast<std::uint16_t>(bound[0].port);
  }
  return server;
}

WebServer::~WebServer() {
  if (context_ != nullptr) mg_stop(context_);
}

int WebServer::handle_request(mg_connection* connection) {
  const mg_request_info* request = mg_get_request_info(connection);
  const std::string_view uri = request->local_uri != nullptr ? request->local_uri : "";
  if (uri == "/scene.json") {
    mg_send_http_ok(connection, "application/json",
                    static_cast<long long>(content_.scene_json.size()));
    mg_write(connection, content_.scene_json.data(), content_.scene_json.size());
    return 200;
  }
  constexpr std::string_view prefix = "/model/";
  constexpr std::string_view suffix = ".bin";
  if (uri.starts_with(prefix) && uri.ends_with(suffix)) {
    const std::string_view digits =
        uri.substr(prefix.size(), uri.size() - prefix.size() - suffix.size());
    std::size_t index = 0;
    bool valid = !digits.empty() && digits.size() < 4;
    for (const char c : digits) {
      valid = valid && c >= '0' && c <= '9';
      index = index * 10 + static_cast<std::size_t>(c - '0');
    }
    if (valid && index < content_.model_blobs.size()) {
      const std::vector<std::byte>& blob = content_.model_blobs[index];
      mg_send_http_ok(connection, "application/octet-stream", static_cast<long long>(blob.size()));
      mg_write(connection, blob.data(), blob.size());
      return 200;
    }
  }
  mg_send_http_error(connection, 404, "%s", "no such model");
  return 404;
}

void WebServer::on_ready(mg_connection* connection) {
  const std::lock_guard lock(mutex_);
  clients_.push_back(connection);
}

void WebServer::on_text(const char* data, std::size_t length) {
  const std::lock_guard lock(mutex_);
  const std::string_view text(data, length);
  // Playback requests are few (a click, a slider move); a page flooding them is capped.
  if (text.find("\"type\":\"playback\"") != std::string_view::npos) {
    if (controls_.size() < 64) controls_.emplace_back(text);
    return;
  }
  page_stats_.assign(data, length);
}

std::vector<std::string> WebServer::take_controls() {
  const std::lock_guard lock(mutex_);
  return std::exchange(controls_, {});
}

void WebServer::on_close(const mg_connection* connection) {
  const std::lock_guard lock(mutex_);
  std::erase(clients_, connection);
}

void WebServer::broadcast_frame(std::vector<std::byte>& frame) {
  const std::lock_guard lock(mutex_);
  ViewFrameEncoder::stamp_handed(frame, realtime_now_ns());
  for (mg_connection* client : clients_) {
    mg_lock_connection(client);
    mg_websocket_write(client, MG_WEBSOCKET_OPCODE_BINARY,
                       reinterpret_cast<const char*>(frame.data()), frame.size());
    mg_unlock_connection(client);
  }
  if (!clients_.empty()) frames_sent_.fetch_add(1);
}

void WebServer::broadcast_text(const std::string& text) {
  const std::lock_guard lock(mutex_);
  for (mg_connection* client : clients_) {
    mg_lock_connection(client);
    mg_websocket_write(client, MG_WEBSOCKET_OPCODE_TEXT, text.data(), text.size());
    mg_unlock_connection(client);
  }
}

std::size_t WebServer::client_count() {
  const std::lock_guard lock(mutex_);
  return clients_.size();
}

std::string WebServer::last_page_stats() {
  const std::lock_guard lock(mutex_);
  return page_stats_;
}

}  // namespace trainer::viewer
