// viewer: the graphics host program (docs/viewer.md). Loads the scene and the same model
// images as the appliance, receives frames from a source (the trainer's telemetry stream over
// UDP; a session recording played back with seek; a synthetic test pattern), rebuilds the deformed surfaces and serves the three.js page
// and the frames over HTTP + WebSocket.
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "frame_source.hpp"
#include "recording_source.hpp"
#include "scene_assets.hpp"
#include "test_pattern_source.hpp"
#include "udp_source.hpp"
#include "view_frame.hpp"
#include "viewer_loop.hpp"
#include "web_server.hpp"

#ifndef TRAINER_VIEWER_WEB_DIR
#define TRAINER_VIEWER_WEB_DIR ""
#endif

namespace {

volatile std::sig_atomic_t g_viewer_stop = 0;
extern "C" void viewer_on_signal(int /*signal*/) {
  g_viewer_stop = 1;
}

std::filesystem::path default_web_root(const char* argv0) {
  // Installed layout first (bin/viewer next to share/viewer), then the build tree's bundle.
  std::error_code error;
  const std::filesystem::path exe = std::filesystem::canonical("/proc/self/exe", error);
  const std::filesystem::path base = error ? std::filesystem::path(argv0) : exe;
  const std::filesystem::path installed = base.parent_path().parent_path() / "share" / "viewer";
  if (std::filesystem::is_regular_file(installed / "index.html", error)) return installed;
  return TRAINER_VIEWER_WEB_DIR;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace trainer;
  CLI::App app{"viewer: draws the trainer's scene live in a browser from its telemetry stream"};
  std::filesystem::path scene_file;
  std::string source_name = "udp";
  std::string udp = "0.0.0.0:47800";
  std::string http_address = "127.0.0.1";
  std::uint16_t http_port = 8080;
  std::filesystem::path web_root = default_web_root(argv[0]);
  std::string reconstruction_name = "viewer";
  double seconds = 0.0;
  double pattern_rate_hz = 60.0;
  std::string metrics_file;
  std::filesystem::path recording_file;
  app.add_option("--scene", scene_file,
                 "scene file the appliance runs (its models' images are loaded)")
      ->required();
  app.add_option("--source", source_name,
                 "frame source: udp (the trainer's stream), recording (a session recording's "
                 "telemetry frames, played back with seek) or test-pattern")
      ->check(CLI::IsMember({"udp", "recording", "test-pattern"}));
  app.add_option("--recording", recording_file,
                 "session recording (trainer --record FILE) to play back (recording source)");
  app.add_option("--udp", udp, "address:port the stream arrives on (udp source)");
  app.add_option("--http-address", http_address,
                 "address the page is served on (0.0.0.0: the LAN)");
  app.add_option("--http-port", http_port, "port the page is served on (0: any free port)");
  app.add_option("--web", web_root, "directory of the bundled page (index.html, viewer.js)");
  app.add_option("--reconstruct", reconstruction_name,
                 "where modal surfaces are rebuilt: viewer (u = Phi q here, 3n floats per frame) "
                 "or browser (Phi sent once, q per frame)")
      ->check(CLI::IsMember({"viewer", "browser"}));
  app.add_option("--seconds", seconds, "stop after this long (0: until SIGINT/SIGTERM)");
  app.add_option("--pattern-rate", pattern_rate_hz, "test-pattern frame rate, Hz")
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--metrics", metrics_file,
                 "JSON file with the trainee metrics for the session panel (re-read every second), "
                 "instead of the metrics the stream carries");
  CLI11_PARSE(app, argc, argv);

  auto assets = viewer::SceneAssets::load(scene_file);
  if (!assets) {
    std::fprintf(stderr, "viewer: %s\n", assets.error().message.c_str());
    return 1;
  }
  const viewer::Reconstruction reconstruction = reconstruction_name == "browser"
                                                    ? viewer::Reconstruction::browser
                                                    : viewer::Reconstruction::viewer;
  viewer::ViewFrameEncoder encoder(**assets, reconstruction);
  viewer::WebContent content;
  content.scene_json = encoder.scene_json();
  for (std::size_t i = 0; i < (*assets)->models().size(); ++i) {
    content.model_blobs.push_back(encoder.model_blob(i));
  }
  auto server = viewer::WebServer::start({http_address, http_port, web_root}, std::move(content));
  if (!server) {
    std::fprintf(stderr, "%s\n", server.error().message.c_str());
    return 1;
  }

  std::unique_ptr<viewer::FrameSource> source;
  if (source_name == "test-pattern") {
    source = std::make_unique<viewer::TestPatternSource>(**assets, pattern_rate_hz);
  } else if (source_name == "recording") {
    if (recording_file.empty()) {
      std::fprintf(stderr, "viewer: --source recording needs --recording FILE\n");
      return 1;
    }
    auto recording = viewer::RecordingSource::open(**assets, recording_file);
    if (!recording) {
      std::fprintf(stderr, "viewer: %s\n", recording.error().message.c_str());
      return 1;
    }
    if (!(*recording)->damage().empty()) {
      std::fprintf(stderr, "viewer: %s: read up to the damage: %s\n", recording_file.c_str(),
                   (*recording)->damage().c_str());
    }
    source = std::move(recording).value();
  } else {
    auto udp_source = viewer::UdpSource::open(**assets, udp);
    if (!udp_source) {
      std::fprintf(stderr, "viewer: %s\n", udp_source.error().message.c_str());
      return 1;
    }
    source = std::move(udp_source).value();
  }

  std::printf("viewer: scene '%s' (%s), %zu model(s):\n", (*assets)->scene_name().c_str(),
              (*assets)->scene_path().c_str(), (*assets)->models().size());
  for (const viewer::ModelAssets& m : (*assets)->models()) {
    std::printf("  model '%s': %u %s, image %s (%zu bytes, checksum %s)\n", m.name.c_str(),
                m.node_count, m.kind == config::ModelKind::catheter ? "particles" : "nodes",
                m.image_path.c_str(), m.image_bytes, viewer::checksum_hex(m.checksum).c_str());
  }
  std::printf("  frames from %s; surfaces rebuilt in the %s\n", source->describe().c_str(),
              reconstruction_name.c_str());
  std::printf("  page at http://%s:%u/\n", http_address.c_str(),
              static_cast<unsigned>((*server)->port()));
  std::fflush(stdout);

  std::signal(SIGINT, viewer_on_signal);
  std::signal(SIGTERM, viewer_on_signal);
  std::vector<std::string> instrument_names;
  for (const viewer::InstrumentAssets& instrument : (*assets)->instruments())
    instrument_names.push_back(instrument.name);
  viewer::LoopSummary summary = viewer::run_viewer_loop(
      *source, encoder, **server, seconds, [] { return g_viewer_stop != 0; }, metrics_file,
      instrument_names);
  viewer::print_summary(summary, **server, *source);
  return 0;
}
