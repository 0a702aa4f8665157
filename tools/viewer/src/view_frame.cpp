#include "view_frame.hpp"

#include <algorithm>
#include <cstring>
#include <ctime>
#include <string>

#include <nlohmann/json.hpp>

#include "reconstruct.hpp"

namespace trainer::viewer {

namespace {

template <class T>
void put_value(std::vector<std::byte>& out, std::size_t offset, T value) {
  std::memcpy(out.data() + offset, &value, sizeof value);
}

template <class T>
void append_value(std::vector<std::byte>& out, T value) {
  const std::size_t at = out.size();
  out.resize(at + sizeof value);
  std::memcpy(out.data() + at, &value, sizeof value);
}

void append_floats(std::vector<std::byte>& out, const float* data, std::size_t count) {
  const std::size_t at = out.size();
  out.resize(at + count * sizeof(float));
  if (count != 0) std::memcpy(out.data() + at, data, count * sizeof(float));
}

const char* kind_name(config::ModelKind kind) {
  switch (kind) {
    case config::ModelKind::modal_shell: return "modal_shell";
    case config::ModelKind::tet_tensor: return "tet_tensor";
    case config::ModelKind::catheter: return "catheter";
  }
  return "unknown";
}

bool browser_rebuilds(Reconstruction reconstruction, const ModelAssets& model) {
  return reconstruction == Reconstruction::browser && model.kind == config::ModelKind::modal_shell;
}

}  // namespace

std::int64_t realtime_now_ns() noexcept {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

ViewFrameEncoder::ViewFrameEncoder(SceneAssets& assets, Reconstruction reconstruction)
    : assets_(assets), reconstruction_(reconstruction) {}

core::Expected<void> ViewFrameEncoder::encode(const SceneFrame& frame,
                                              std::vector<std::byte>& out) {
  std::span<ModelAssets> models = assets_.models();
  std::span<const InstrumentAssets> instruments = assets_.instruments();
  if (frame.models.size() != models.size() || frame.instruments.size() != instruments.size()) {
    return core::make_error("frame has " + std::to_string(frame.models.size()) + " models and " +
                            std::to_string(frame.instruments.size()) + " instruments, scene '" +
                            assets_.scene_name() + "' " + std::to_string(models.size()) + " and " +
                            std::to_string(instruments.size()));
  }
  out.assign(kViewFrameHeaderBytes, std::byte{0});
  put_value(out, 0, kViewFrameMagic);
  put_value(out, 4, static_cast<std::uint32_t>(kViewFrameHeaderBytes));
  put_value(out, 8, frame.sequence);
  put_value(out, 16, frame.cycle);
  put_value(out, 24, frame.times.cycle_ns);
  put_value(out, 32, frame.times.sent_ns);
  put_value(out, 40, frame.times.received_ns);
  put_value(out, 64, frame.latched_faults);
  put_value(out, 68, reconstruction_ == Reconstruction::browser ? 1U : 0U);
  put_value(out, 72, static_cast<std::uint32_t>(models.size()));
  put_value(out, 76, static_cast<std::uint32_t>(instruments.size()));

  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < models.size(); ++i) {
    ModelAssets& model = models[i];
    const ModelState& state = frame.models[i];
    if (model.kind == config::ModelKind::catheter) {
      append_value(out, static_cast<std::uint32_t>(3 * state.particles_m.size()));
      append_value(out, 0U);
      for (const auto& p : state.particles_m) append_floats(out, p.data(), 3);
      continue;
    }
    if (browser_rebuilds(reconstruction_, model)) {
      append_value(out, static_cast<std::uint32_t>(state.modal_coordinates.size()));
      append_value(out, static_cast<std::uint32_t>(state.loads.size()));
      append_floats(out, state.modal_coordinates.data(), state.modal_coordinates.size());
      for (const NodeLoad& load : state.loads) {
        append_value(out, load.node);
        append_floats(out, load.force_n.data(), 3);
      }
      continue;
    }
    scratch_.assign(3U * model.node_count, 0.0F);
    auto rebuilt = model.kind == config::ModelKind::modal_shell
                       ? reconstruct_modal(model, state, scratch_)
                       : reconstruct_tensor(model, state, scratch_);
    if (!rebuilt) return std::move(rebuilt).error();
    append_value(out, static_cast<std::uint32_t>(scratch_.size()));
    append_value(out, 0U);
    append_floats(out, scratch_.data(), scratch_.size());
  }
  const double reconstruct_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
  put_value(out, 56, reconstruct_us);

  for (const InstrumentState& state : frame.instruments) {
    float values[kInstrumentFloats];
    std::copy_n(state.shaft_start_m.data(), 3, values);
    std::copy_n(state.hinge_m.data(), 3, values + 3);
    std::copy_n(state.jaw_tips_m[0].data(), 3, values + 6);
    std::copy_n(state.jaw_tips_m[1].data(), 3, values + 9);
    std::copy_n(state.force_n.data(), 3, values + 12);
    values[15] = static_cast<float>(state.flags);
    append_floats(out, values, kInstrumentFloats);
  }
  append_value(out, static_cast<std::uint32_t>(frame.contacts.size()));
  for (const ContactArrow& contact : frame.contacts) {
    float values[kContactFloats];
    std::copy_n(contact.point_m.data(), 3, values);
    std::copy_n(contact.force_n.data(), 3, values + 3);
    values[6] = static_cast<float>(contact.instrument);
    append_floats(out, values, kContactFloats);
  }
  return {};
}

void ViewFrameEncoder::stamp_handed(std::vector<std::byte>& frame, std::int64_t ns) noexcept {
  if (frame.size() >= kViewFrameHeaderBytes) put_value(frame, kViewFrameHandedOffset, ns);
}

std::string ViewFrameEncoder::scene_json() const {
  nlohmann::json scene;
  scene["scene"] = assets_.scene_name();
  scene["frame_format"] = "TVF1";
  scene["period_s"] = assets_.period_s();
  scene["reconstruction"] = reconstruction_ == Reconstruction::browser ? "browser" : "viewer";
  nlohmann::json models = nlohmann::json::array();
  const std::span<const ModelAssets> all = assets_.models();
  for (std::size_t i = 0; i < all.size(); ++i) {
    const ModelAssets& m = all[i];
    nlohmann::json entry;
    entry["name"] = m.name;
    entry["kind"] = kind_name(m.kind);
    entry["node_count"] = m.node_count;
    entry["triangle_count"] = m.triangles.size() / 3;
    entry["mode_count"] = m.mode_count;
    entry["surface_node_count"] = m.surface_nodes.size();
    entry["static_correction"] = m.static_correction;
    entry["checksum"] = checksum_hex(m.checksum);
    entry["browser_rebuilds"] = browser_rebuilds(reconstruction_, m);
    const auto& r = m.placement.rotation();
    const auto& t = m.placement.translation_m();
    entry["rotation"] = {r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1),
                         r(1, 2), r(2, 0), r(2, 1), r(2, 2)};
    entry["translation_m"] = {t(0), t(1), t(2)};
    entry["data"] = "/model/" + std::to_string(i) + ".bin";
    // Offsets (in 4-byte words) and lengths of the arrays in model_blob(i).
    std::size_t word = 0;
    auto section = [&entry, &word](const char* name, std::size_t count) {
      entry["layout"][name] = {word, count};
      word += count;
    };
    section("rest_positions", m.rest_positions.size());
    section("triangles", m.triangles.size());
    if (browser_rebuilds(reconstruction_, m)) {
      section("mode_shapes", m.mode_shapes.size());
      section("omega_squared", m.omega_squared.size());
      section("surface_nodes", m.surface_nodes.size());
      section("residual_compliance", m.static_correction ? m.residual_compliance.size() : 0U);
    }
    models.push_back(std::move(entry));
  }
  scene["models"] = std::move(models);
  nlohmann::json instruments = nlohmann::json::array();
  for (const InstrumentAssets& instrument : assets_.instruments()) {
    instruments.push_back({{"name", instrument.name},
                           {"jaw_length_m", instrument.kinematics.geometry().jaw_length_m}});
  }
  scene["instruments"] = std::move(instruments);
  return scene.dump();
}

std::vector<std::byte> ViewFrameEncoder::model_blob(std::size_t index) const {
  const ModelAssets& m = assets_.models()[index];
  std::vector<std::byte> out;
  auto append_u32s = [&out](std::span<const std::uint32_t> v) {
    const std::size_t at = out.size();
    out.resize(at + v.size_bytes());
    if (!v.empty()) std::memcpy(out.data() + at, v.data(), v.size_bytes());
  };
  append_floats(out, m.rest_positions.data(), m.rest_positions.size());
  append_u32s(m.triangles);
  if (browser_rebuilds(reconstruction_, m)) {
    append_floats(out, m.mode_shapes.data(), m.mode_shapes.size());
    append_floats(out, m.omega_squared.data(), m.omega_squared.size());
    append_u32s(m.surface_nodes);
    if (m.static_correction) {
      append_floats(out, m.residual_compliance.data(), m.residual_compliance.size());
    }
  }
  return out;
}

}  // namespace trainer::viewer
