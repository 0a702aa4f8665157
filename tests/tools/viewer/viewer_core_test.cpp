// The viewer's core on the cbd scene's real images (built by viewer_core_test.sh with modelc
// into a temporary copy of config/, path in VIEWER_TEST_SCENE): reconstruction against the
// runtime ModalModel it mirrors, the checksum refusal, the UDP source over loopback with frames
// encoded by the telemetry wire library (ordering, duplicates, malformed and foreign-image
// datagrams), the recording source's playback (seek, pause, speed, end, a truncated file),
// and the page frame's layout.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "reconstruct.hpp"
#include "scene_assets.hpp"
#include "viewer_loop.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/telemetry/wire_format.hpp"
#include "recording_source.hpp"
#include "trainer/record/recording.hpp"
#include "udp_source.hpp"
#include "view_frame.hpp"

namespace trainer::viewer {
namespace {

SceneAssets& assets() {
  static std::unique_ptr<SceneAssets> loaded = [] {
    const char* scene = std::getenv("VIEWER_TEST_SCENE");
    if (scene == nullptr) {
      ADD_FAILURE() << "VIEWER_TEST_SCENE not set (run through viewer_core_test.sh)";
      return std::unique_ptr<SceneAssets>{};
    }
    auto result = SceneAssets::load(scene);
    if (!result) {
      ADD_FAILURE() << result.error().message;
      return std::unique_ptr<SceneAssets>{};
    }
    return std::move(result).value();
  }();
  return *loaded;
}

const ModelAssets& duct() {
  return assets().models()[0];
}

// Runs the runtime modal model on the duct image with two surface loads for a few steps and
// checks reconstruct_modal on (its q, its loads) against ModalModel::reconstruct.
void expect_matches_runtime(std::uint32_t active_modes) {
  ASSERT_EQ(duct().kind, config::ModelKind::modal_shell);
  ASSERT_TRUE(duct().static_correction);
  auto arena = core::Arena::create(16U << 20U);
  ASSERT_TRUE(arena);
  auto image = model::load_model_image(duct().image_path, *arena, model::ImageLimits{},
                                       model::ModelKind::modal_shell);
  ASSERT_TRUE(image) << image.error().message;
  model::ModalSettings settings;
  settings.time_step_s = 1e-3F;
  settings.active_modes = active_modes;
  settings.static_correction = true;
  auto runtime = model::ModalModel::create(model::modal_model_data(*image), *arena, settings);
  ASSERT_TRUE(runtime) << runtime.error().message;
  const std::uint32_t a = duct().surface_nodes[duct().surface_nodes.size() / 2];
  const std::uint32_t b = duct().surface_nodes.back();
  ModelState state;
  state.loads = {NodeLoad{a, {0.0F, 0.2F, -0.3F}}, NodeLoad{b, {0.1F, 0.0F, 0.05F}}};
  for (int step = 0; step < 12; ++step) {
    runtime->clear_forces();
    for (const NodeLoad& load : state.loads) {
      ASSERT_TRUE(runtime->add_node_force(
          load.node, model::Vec3(load.force_n[0], load.force_n[1], load.force_n[2])));
    }
    ASSERT_TRUE(runtime->step());
  }
  std::vector<float> expected(3U * duct().node_count);
  ASSERT_TRUE(runtime->reconstruct(expected));
  for (const double q : runtime->modal_displacement())
    state.modal_coordinates.push_back(static_cast<float>(q));
  ASSERT_EQ(state.modal_coordinates.size(), active_modes == 0 ? duct().mode_count : active_modes);
  std::vector<float> rebuilt(3U * duct().node_count);
  ASSERT_TRUE(reconstruct_modal(duct(), state, rebuilt));
  float largest = 0.0F;
  float worst = 0.0F;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    largest = std::max(largest, std::abs(expected[i]));
    worst = std::max(worst, std::abs(expected[i] - rebuilt[i]));
  }
  EXPECT_GT(largest, 1e-6F) << "the loads moved nothing";
  EXPECT_LT(worst, 1e-4F * largest) << "largest " << largest;
}

// The session panel's trainee metrics from a frame's metrics section (wire format 1.1): task
// state, insertion only with a goal, instruments by their scene names, lengths in mm.
TEST(ViewerPanel, StreamMetricsBecomeThePanelsObject) {
  telemetry::SessionMetrics m;
  m.flags = telemetry::kMetricsTaskStarted | telemetry::kMetricsInsertionGoal;
  m.task_time_s = 4.25F;
  m.insertion_depth_m = 0.0075F;
  m.instrument_count = 2;
  m.instruments[0].path_length_m = 0.075F;
  m.instruments[0].grasps = 1;
  m.instruments[1].movements = 3;
  const nlohmann::json panel = nlohmann::json::parse(stream_metrics_json(m, {"left", "right"}));
  EXPECT_EQ(panel["task"], "in progress");
  EXPECT_DOUBLE_EQ(panel["task_time_s"].get<double>(), 4.25);
  EXPECT_DOUBLE_EQ(panel["insertion_depth_mm"].get<double>(), 7.5);
  EXPECT_EQ(panel["time_to_target_s"], "not reached");
  EXPECT_DOUBLE_EQ(panel["left"]["path_mm"].get<double>(), 75.0);
  EXPECT_EQ(panel["left"]["grasps"], 1);
  EXPECT_EQ(panel["right"]["movements"], 3);
  m.flags = telemetry::kMetricsTaskStarted | telemetry::kMetricsTaskCompleted;
  const nlohmann::json done = nlohmann::json::parse(stream_metrics_json(m, {}));
  EXPECT_EQ(done["task"], "completed");
  EXPECT_FALSE(done.contains("insertion_depth_mm"));
  EXPECT_TRUE(done.contains("instrument 0"));
}

TEST(ViewerReconstruct, ModalMatchesTheRuntimeWithStaticCorrection) {
  expect_matches_runtime(0);
}

TEST(ViewerReconstruct, ModalMatchesTheRuntimeOverFewerModesThanStored) {
  expect_matches_runtime(20);
}

TEST(ViewerReconstruct, ModalWithoutLoadsIsPhiQ) {
  ModelState state;
  state.modal_coordinates.assign(duct().mode_count, 0.0F);
  state.modal_coordinates[2] = 1e-4F;
  std::vector<float> rebuilt(3U * duct().node_count);
  ASSERT_TRUE(reconstruct_modal(duct(), state, rebuilt));
  for (std::size_t row = 0; row < rebuilt.size(); ++row) {
    EXPECT_FLOAT_EQ(rebuilt[row], duct().mode_shapes[row * duct().mode_count + 2] * 1e-4F);
  }
  state.modal_coordinates.resize(duct().mode_count + 1);
  EXPECT_FALSE(reconstruct_modal(duct(), state, rebuilt));
}

TEST(ViewerAssets, RefusesAStreamOfOtherImages) {
  std::vector<std::uint64_t> sums;
  for (const ModelAssets& m : assets().models()) sums.push_back(m.checksum);
  EXPECT_TRUE(assets().check_checksums(sums));
  sums[0] ^= 1U;
  auto refused = assets().check_checksums(sums);
  ASSERT_FALSE(refused);
  const std::string& message = refused.error().message;
  EXPECT_NE(message.find("model 'duct'"), std::string::npos) << message;
  EXPECT_NE(message.find(checksum_hex(sums[0])), std::string::npos) << message;
  EXPECT_NE(message.find(checksum_hex(duct().checksum)), std::string::npos) << message;
  EXPECT_NE(message.find(duct().image_path.string()), std::string::npos) << message;
  sums.pop_back();
  EXPECT_FALSE(assets().check_checksums(sums));
}

// A telemetry frame of the scene as the appliance would send it.
std::unique_ptr<telemetry::Frame> wire_frame(std::uint64_t sequence) {
  auto frame = std::make_unique<telemetry::Frame>();
  frame->stream_id = 7;
  frame->sequence = sequence;
  frame->cycle = 1000 + sequence;
  frame->cycle_time_ns = 5'000'000;
  frame->send_time_ns = 5'400'000;
  frame->send_wall_ns = 1'800'000'000'000'000'000;
  frame->model_count = static_cast<std::uint32_t>(assets().models().size());
  for (std::size_t i = 0; i < assets().models().size(); ++i) {
    const ModelAssets& m = assets().models()[i];
    telemetry::ModelState& s = frame->models[i];
    s.scene_index = static_cast<std::uint8_t>(i);
    s.image_checksum = m.checksum;
    if (m.kind == config::ModelKind::modal_shell) {
      s.kind = telemetry::ModelKind::modal;
      s.mode_count = m.mode_count;
      s.modal_coordinates[0] = 1e-4F * static_cast<float>(sequence);
    } else {
      s.kind = telemetry::ModelKind::catheter;
      s.particle_count = m.node_count;
      for (std::uint32_t p = 0; p < m.node_count; ++p) {
        s.particles_m[p] = {m.rest_positions[3 * p], m.rest_positions[3 * p + 1],
                            m.rest_positions[3 * p + 2]};
      }
    }
  }
  frame->instrument_count = static_cast<std::uint32_t>(assets().instruments().size());
  for (std::uint32_t i = 0; i < frame->instrument_count; ++i) {
    telemetry::InstrumentState& s = frame->instruments[i];
    s.hinge_m = {0.0F, 0.0F, -0.085F};
    s.tip_m = {0.0F, 0.0F, -0.1F};
    s.shaft_start_m = {0.0F, 0.0F, 0.2F};
    s.opening_direction = {0.0F, 1.0F, 0.0F};
    s.grip_rad = 0.5F;
  }
  frame->contact_count = 1;
  frame->contacts[0].point_m = {0.0F, 0.0F, -0.1F};
  frame->contacts[0].force_n = {0.0F, 0.0F, -0.5F};
  return frame;
}

class Sender {
 public:
  explicit Sender(std::uint16_t port) : fd_(socket(AF_INET, SOCK_DGRAM, 0)) {
    to_.sin_family = AF_INET;
    to_.sin_port = htons(port);
    inet_pton(AF_INET, "127.0.0.1", &to_.sin_addr);
  }
  ~Sender() { close(fd_); }
  void send(std::span<const std::byte> bytes) {
    ASSERT_EQ(sendto(fd_, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to_),
                     sizeof to_),
              static_cast<ssize_t>(bytes.size()));
  }
  void send(const telemetry::Frame& frame) {
    std::vector<std::byte> bytes(telemetry::kMaxDatagramBytes);
    const telemetry::EncodeResult encoded = telemetry::encode(frame, bytes);
    ASSERT_TRUE(encoded.ok()) << encoded.error;
    send({bytes.data(), encoded.bytes});
  }

 private:
  int fd_;
  sockaddr_in to_{};
};

TEST(ViewerUdpSource, DecodesOrdersAndRefuses) {
  auto source = UdpSource::open(assets(), "127.0.0.1:0");
  ASSERT_TRUE(source) << source.error().message;
  Sender sender((*source)->port());
  SceneFrame frame;
  auto next = [&]() { return (*source)->next(frame, std::chrono::milliseconds(500)); };

  sender.send(*wire_frame(1));
  auto got = next();
  ASSERT_TRUE(got) << got.error().message;
  ASSERT_TRUE(*got);
  EXPECT_EQ(frame.sequence, 1U);
  EXPECT_EQ(frame.cycle, 1001U);
  EXPECT_EQ(frame.times.sent_ns, 1'800'000'000'000'000'000);
  EXPECT_EQ(frame.times.cycle_ns, 1'800'000'000'000'000'000 - 400'000);
  EXPECT_GT(frame.times.received_ns, 0);
  ASSERT_EQ(frame.models.size(), assets().models().size());
  EXPECT_FLOAT_EQ(frame.models[0].modal_coordinates[0], 1e-4F);
  ASSERT_EQ(frame.instruments.size(), 2U);
  // Jaws opened by 0.5 rad about the hinge in the plane of the shaft and the opening direction.
  const auto& jaw = frame.instruments[0].jaw_tips_m[0];
  EXPECT_NEAR(jaw[1], 0.015F * std::sin(0.25F), 1e-6F);
  EXPECT_NEAR(jaw[2], -0.085F - 0.015F * std::cos(0.25F), 1e-6F);
  ASSERT_EQ(frame.contacts.size(), 1U);

  sender.send(*wire_frame(3));
  got = next();
  ASSERT_TRUE(got && *got);
  EXPECT_EQ(frame.sequence, 3U);
  sender.send(*wire_frame(2));  // late: dropped
  got = next();
  ASSERT_TRUE(got);
  EXPECT_FALSE(*got);
  sender.send(*wire_frame(3));  // duplicate: dropped
  got = next();
  ASSERT_TRUE(got);
  EXPECT_FALSE(*got);

  auto foreign = wire_frame(4);
  foreign->models[0].image_checksum ^= 0xFF;
  sender.send(*foreign);
  got = next();
  ASSERT_FALSE(got);
  EXPECT_NE(got.error().message.find("stream refused: model 'duct'"), std::string::npos)
      << got.error().message;

  const std::byte junk[80] = {};
  sender.send(junk);
  got = next();
  ASSERT_FALSE(got);
  EXPECT_NE(got.error().message.find("malformed datagram"), std::string::npos)
      << got.error().message;

  sender.send(*wire_frame(5));
  got = next();
  ASSERT_TRUE(got && *got);
  EXPECT_EQ(frame.sequence, 5U);
  const std::string stats = (*source)->stats_json();
  EXPECT_NE(stats.find("\"duplicates\":1"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"late\":1"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"malformed\":1"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"refused\":1"), std::string::npos) << stats;
}

// A session recording with only telemetry frames on channel 2: `count` frames at 60 Hz of log
// time (cycle = 1000 + k), a chunk every 30 frames.
std::filesystem::path playback_recording(const std::string& name, std::uint64_t count) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("viewer_playback_" + std::to_string(getpid()) + "_" + name +
                                      ".mcap");
  record::RecordingWriter writer;
  EXPECT_TRUE(writer.open(path, {{"scene_name", "cbd"}}));
  std::vector<std::byte> bytes(telemetry::kMaxDatagramBytes);
  for (std::uint64_t k = 0; k < count; ++k) {
    auto frame = wire_frame(k);
    frame->cycle_time_ns = 7'000'000'000 + static_cast<std::int64_t>(k) * 16'666'667;
    const telemetry::EncodeResult encoded = telemetry::encode(*frame, bytes);
    EXPECT_TRUE(encoded.ok()) << encoded.error;
    EXPECT_TRUE(writer.add_telemetry({bytes.data(), encoded.bytes}, frame->cycle_time_ns, k));
    if (k % 30 == 29) {
      EXPECT_TRUE(writer.flush());
    }
  }
  EXPECT_TRUE(writer.close(0));
  return path;
}

TEST(ViewerRecordingSource, SeekPausePlaySpeedAndEnd) {
  const auto path = playback_recording("seek", 120);
  std::int64_t now = 0;
  auto source = RecordingSource::open(assets(), path, [&now] { return now; });
  ASSERT_TRUE(source) << source.error().message;
  RecordingSource& s = **source;
  EXPECT_EQ(s.frame_count(), 120U);
  EXPECT_NEAR(s.duration_s(), 119 * 0.016666667, 1e-6);
  EXPECT_EQ(s.damage(), "");
  SceneFrame frame;
  auto next = [&] {
    auto got = s.next(frame, std::chrono::milliseconds(0));
    EXPECT_TRUE(got) << got.error().message;
    return got && *got;
  };
  // Playing: the frame due at the clock, nothing new until the next one is due.
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1000U);
  EXPECT_FALSE(next());
  now = 505'000'000;  // 0.505 s: frame 30 is at 0.50000001 s
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1030U);
  EXPECT_EQ(frame.times.sent_ns, 0);  // no hop latencies for a recorded frame
  // Seek to just after 1.0 s: frame 60; seek between frames: the one before.
  s.control(R"({"type":"playback","action":"seek","t":1.005})");
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1060U);
  s.control(R"({"type":"playback","action":"seek","t":0.26})");
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1015U);
  // Pause holds: a second later nothing new, position unchanged; a seek while paused shows.
  s.control(R"({"type":"playback","action":"pause"})");
  now += 1'000'000'000;
  EXPECT_FALSE(next());
  EXPECT_NEAR(s.position_s(), 0.26, 1e-6);
  EXPECT_TRUE(s.paused());
  s.control(R"({"type":"playback","action":"seek","t":1.505})");
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1090U);
  now += 1'000'000'000;
  EXPECT_FALSE(next());
  // Play at double speed: 0.25 s of clock is 0.5 s of recording.
  s.control(R"({"type":"playback","action":"speed","speed":2})");
  s.control(R"({"type":"playback","action":"play"})");
  now += 250'000'000;
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1119U);  // 2.0 s is past the end (1.983 s): the last frame
  EXPECT_TRUE(s.ended());
  EXPECT_FALSE(next());
  EXPECT_NE(s.playback_json().find("\"ended\":true"), std::string::npos) << s.playback_json();
  // Play at the end starts again from the first frame; junk requests change nothing.
  s.control(R"({"type":"playback","action":"play"})");
  s.control("not json");
  s.control(R"({"type":"playback","action":"seek","t":"x"})");
  ASSERT_TRUE(next());
  EXPECT_EQ(frame.cycle, 1000U);
  EXPECT_FALSE(s.ended());
  std::filesystem::remove(path);
}

TEST(ViewerRecordingSource, TruncatedFileIsReadUpToTheDamage) {
  const auto whole = playback_recording("whole", 120);
  const auto cut = std::filesystem::path(whole.string() + ".cut");
  const auto size = std::filesystem::file_size(whole);
  {
    std::ifstream in(whole, std::ios::binary);
    std::vector<char> bytes(size / 2);
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    std::ofstream out(cut, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  auto source = RecordingSource::open(assets(), cut, [] { return std::int64_t{0}; });
  ASSERT_TRUE(source) << source.error().message;
  EXPECT_GT((*source)->frame_count(), 0U);
  EXPECT_LT((*source)->frame_count(), 120U);
  EXPECT_EQ((*source)->frame_count() % 30, 0U);  // whole chunks only
  EXPECT_NE((*source)->damage(), "");
  EXPECT_NE((*source)->describe().find("read up to the damage"), std::string::npos)
      << (*source)->describe();
  // A file with no telemetry frames is refused, saying so.
  const auto empty = playback_recording("none", 0);
  auto refused = RecordingSource::open(assets(), empty);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("no telemetry frames"), std::string::npos)
      << refused.error().message;
  std::filesystem::remove(whole);
  std::filesystem::remove(cut);
  std::filesystem::remove(empty);
}

TEST(ViewerPageFrame, LayoutAndPlacements) {
  SceneFrame frame;
  ASSERT_TRUE(scene_frame_from_telemetry(assets(), *wire_frame(2), frame));
  const std::size_t n = duct().node_count;
  const std::size_t particles = assets().models()[1].node_count;
  for (const Reconstruction where : {Reconstruction::viewer, Reconstruction::browser}) {
    ViewFrameEncoder encoder(assets(), where);
    std::vector<std::byte> out;
    ASSERT_TRUE(encoder.encode(frame, out));
    const std::size_t duct_floats = where == Reconstruction::viewer ? 3 * n : duct().mode_count;
    EXPECT_EQ(out.size(), kViewFrameHeaderBytes + 8 + 4 * duct_floats + 8 + 4 * 3 * particles +
                              2 * 4 * kInstrumentFloats + 4 + 4 * kContactFloats);
    std::uint32_t magic = 0;
    std::uint64_t cycle = 0;
    std::memcpy(&magic, out.data(), 4);
    std::memcpy(&cycle, out.data() + 16, 8);
    EXPECT_EQ(magic, kViewFrameMagic);
    EXPECT_EQ(cycle, 1002U);
    // The duct's rebuilt displacements (viewer side) are Φ q: spot-check node 100.
    if (where == Reconstruction::viewer) {
      float u = 0.0F;
      std::memcpy(&u, out.data() + kViewFrameHeaderBytes + 8 + 4 * 300, 4);
      EXPECT_FLOAT_EQ(u, duct().mode_shapes[300 * duct().mode_count] * 2e-4F);
    }
  }
  frame.instruments.pop_back();
  ViewFrameEncoder encoder(assets(), Reconstruction::viewer);
  std::vector<std::byte> out;
  EXPECT_FALSE(encoder.encode(frame, out));
}

}  // namespace
}  // namespace trainer::viewer

namespace trainer::viewer {
namespace {

// With VIEWER_TEST_JS_FIXTURE=DIR: writes what the page gets in browser mode (scene.json, the
// duct's data) plus a state and the C++ rebuild of it, for check_browser_rebuild.mjs to compare
// web/src/reconstruct.js against.
TEST(ViewerReconstruct, WritesTheBrowserRebuildFixture) {
  const char* dir = std::getenv("VIEWER_TEST_JS_FIXTURE");
  if (dir == nullptr) GTEST_SKIP() << "VIEWER_TEST_JS_FIXTURE not set";
  ViewFrameEncoder encoder(assets(), Reconstruction::browser);
  ModelState state;
  for (std::uint32_t i = 0; i < 24; ++i) {
    state.modal_coordinates.push_back(1e-5F * static_cast<float>(i % 5) - 2e-5F);
  }
  state.loads = {NodeLoad{duct().surface_nodes[7], {0.3F, -0.1F, 0.2F}},
                 NodeLoad{duct().surface_nodes[200], {0.0F, 0.4F, -0.25F}}};
  std::vector<float> expected(3U * duct().node_count);
  ASSERT_TRUE(reconstruct_modal(duct(), state, expected));
  auto write = [dir](const char* name, const void* data, std::size_t bytes) {
    FILE* file = std::fopen((std::string(dir) + "/" + name).c_str(), "wb");
    ASSERT_NE(file, nullptr);
    ASSERT_EQ(std::fwrite(data, 1, bytes, file), bytes);
    std::fclose(file);
  };
  const std::string scene = encoder.scene_json();
  write("scene.json", scene.data(), scene.size());
  const std::vector<std::byte> blob = encoder.model_blob(0);
  write("model0.bin", blob.data(), blob.size());
  write("coordinates.bin", state.modal_coordinates.data(), 4 * state.modal_coordinates.size());
  nlohmann::json load_list = nlohmann::json::array();
  for (const NodeLoad& load : state.loads) {
    load_list.push_back({{"node", load.node}, {"force", load.force_n}});
  }
  const std::string loads = load_list.dump();
  write("loads.json", loads.data(), loads.size());
  write("expected.bin", expected.data(), 4 * expected.size());
}

}  // namespace
}  // namespace trainer::viewer
