// Sends the cbd scene's telemetry as the appliance would, for the viewer's tests until (and
// besides) the trainer's own sender: frames encoded by the telemetry wire library at a fixed
// rate to 127.0.0.1:PORT, with the scene's image checksums, the duct's first modes swinging
// (a few mm), a tensor model pressed at one contact node (up to 4 mm), the instruments still, the
// catheter at rest, real timestamps (cycle = send instant, CLOCK_MONOTONIC and CLOCK_REALTIME as
// the appliance stamps them). usage: telemetry_test_sender SCENE PORT SECONDS [RATE_HZ]
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <memory>
#include <numbers>
#include <thread>
#include <vector>

#include "scene_assets.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace {

std::int64_t sender_clock_ns(clockid_t clock) {
  timespec now{};
  clock_gettime(clock, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace trainer;
  if (argc < 4) {
    std::fprintf(stderr, "usage: telemetry_test_sender SCENE PORT SECONDS [RATE_HZ]\n");
    return 2;
  }
  auto assets = viewer::SceneAssets::load(argv[1]);
  if (!assets) {
    std::fprintf(stderr, "telemetry_test_sender: %s\n", assets.error().message.c_str());
    return 1;
  }
  const auto port = static_cast<std::uint16_t>(std::atoi(argv[2]));
  const double seconds = std::atof(argv[3]);
  const double rate_hz = argc > 4 ? std::atof(argv[4]) : 60.0;
  const double fault_after_s = argc > 5 ? std::atof(argv[5]) : -1.0;
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);

  auto frame = std::make_unique<telemetry::Frame>();
  frame->stream_id = static_cast<std::uint32_t>(getpid());
  const auto models = (*assets)->models();
  frame->model_count = static_cast<std::uint32_t>(models.size());
  for (std::size_t i = 0; i < models.size(); ++i) {
    telemetry::ModelState& s = frame->models[i];
    s.scene_index = static_cast<std::uint8_t>(i);
    s.image_checksum = models[i].checksum;
    switch (models[i].kind) {
      case config::ModelKind::modal_shell:
        s.kind = telemetry::ModelKind::modal;
        s.mode_count = models[i].mode_count;
        break;
      case config::ModelKind::tet_tensor:
        s.kind = telemetry::ModelKind::tensor;
        s.contact_count = models[i].surface_nodes.empty() ? 0U : 1U;  // pressed below (swinging)
        if (s.contact_count != 0) s.contacts[0].node = models[i].surface_nodes[0];
        // The top contact node nearest the middle of the top face (largest z, then smallest
        // |x|+|y|).
        for (const std::uint32_t node : models[i].surface_nodes) {
          const float* p = models[i].rest_positions.data() + 3U * node;
          const float* q = models[i].rest_positions.data() + 3U * s.contacts[0].node;
          if (p[2] > q[2] + 1e-6F || (p[2] > q[2] - 1e-6F && std::abs(p[0]) + std::abs(p[1]) <
                                                                 std::abs(q[0]) + std::abs(q[1]))) {
            s.contacts[0].node = node;
          }
        }
        break;
      case config::ModelKind::catheter:
        s.kind = telemetry::ModelKind::catheter;
        s.particle_count = models[i].node_count;
        for (std::uint32_t p = 0; p < models[i].node_count; ++p) {
          s.particles_m[p] = {models[i].rest_positions[3 * p], models[i].rest_positions[3 * p + 1],
                              models[i].rest_positions[3 * p + 2]};
        }
        break;
    }
  }
  const auto instruments = (*assets)->instruments();
  frame->instrument_count = static_cast<std::uint32_t>(instruments.size());
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    const kinematics::InstrumentPose pose = instruments[i].kinematics.forward(
        {0.25F * (i == 0 ? 1.0F : -1.0F), 0.0F, 0.09F, 0.0F, 0.4F});
    telemetry::InstrumentState& s = frame->instruments[i];
    s.tip_m = {pose.tip_m.x(), pose.tip_m.y(), pose.tip_m.z()};
    s.hinge_m = {pose.hinge_m.x(), pose.hinge_m.y(), pose.hinge_m.z()};
    s.shaft_start_m = {pose.shaft_start_m.x(), pose.shaft_start_m.y(), pose.shaft_start_m.z()};
    s.opening_direction = {pose.opening_direction.x(), pose.opening_direction.y(),
                           pose.opening_direction.z()};
    s.grip_rad = 0.4F;
  }
  std::vector<std::byte> bytes(telemetry::kMaxDatagramBytes);
  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz));
  const auto start = std::chrono::steady_clock::now();
  auto due = start;
  std::size_t size = 0;
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() <
         seconds) {
    std::this_thread::sleep_until(due);
    due += period;
    const double t =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++frame->sequence;
    frame->cycle = static_cast<std::uint64_t>(t * 1000.0);
    frame->latched_faults = fault_after_s >= 0.0 && t >= fault_after_s ? 0x4U : 0U;
    for (std::size_t i = 0; i < models.size(); ++i) {
      if (models[i].kind == config::ModelKind::tet_tensor && frame->models[i].contact_count != 0) {
        frame->models[i].contacts[0].displacement_m = {
            0.0F, 0.0F,
            static_cast<float>(-0.004 * (0.5 + 0.5 * std::sin(2.0 * std::numbers::pi * t)))};
      }
      if (models[i].kind != config::ModelKind::modal_shell) continue;
      for (std::uint32_t k = 0; k < 3 && k < models[i].mode_count; ++k) {
        frame->models[i].modal_coordinates[k] =
            static_cast<float>(6e-5 * std::sin(2.0 * std::numbers::pi * t + k));
      }
    }
    frame->cycle_time_ns = sender_clock_ns(CLOCK_MONOTONIC);
    frame->send_time_ns = sender_clock_ns(CLOCK_MONOTONIC);
    frame->send_wall_ns = sender_clock_ns(CLOCK_REALTIME);
    const telemetry::EncodeResult encoded = telemetry::encode(*frame, bytes);
    if (!encoded.ok()) {
      std::fprintf(stderr, "telemetry_test_sender: encode: %s\n", encoded.error);
      return 1;
    }
    size = encoded.bytes;
    sendto(fd, bytes.data(), encoded.bytes, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to);
  }
  std::printf("telemetry_test_sender: %llu frames of %zu bytes\n",
              static_cast<unsigned long long>(frame->sequence), size);
  close(fd);
  return 0;
}
