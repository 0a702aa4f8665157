#include "reconstruct.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace trainer::viewer {

core::Expected<void> reconstruct_modal(const ModelAssets& model, const ModelState& state,
                                       std::span<float> out) {
  const std::size_t n3 = 3U * model.node_count;
  const std::size_t stored = model.mode_count;
  const std::size_t streamed = state.modal_coordinates.size();
  if (out.size() < n3) return core::make_error("reconstruct: output shorter than 3n");
  if (streamed > stored) {
    return core::make_error("model '" + model.name + "': " + std::to_string(streamed) +
                            " modal coordinates on the stream, the image stores " +
                            std::to_string(stored) + " modes");
  }
  for (const NodeLoad& load : state.loads) {
    if (load.node >= model.node_count) {
      return core::make_error("model '" + model.name + "': load on node " +
                              std::to_string(load.node) + " of " +
                              std::to_string(model.node_count));
    }
  }
  // Effective coordinates: the streamed ones, then the static response of the modes left out.
  std::vector<float> q(stored, 0.0F);
  std::copy(state.modal_coordinates.begin(), state.modal_coordinates.end(), q.begin());
  const bool correct = model.static_correction && !state.loads.empty();
  if (correct && streamed < stored) {
    for (std::size_t i = streamed; i < stored; ++i) {
      double projected = 0.0;
      for (const NodeLoad& load : state.loads) {
        for (std::size_t a = 0; a < 3; ++a) {
          projected += static_cast<double>(model.mode_shapes[(3U * load.node + a) * stored + i]) *
                       static_cast<double>(load.force_n[a]);
        }
      }
      q[i] = static_cast<float>(projected / static_cast<double>(model.omega_squared[i]));
    }
  }
  const std::size_t used = correct ? stored : streamed;
  for (std::size_t row = 0; row < n3; ++row) {
    const float* shape = model.mode_shapes.data() + row * stored;
    float sum = 0.0F;
    for (std::size_t i = 0; i < used; ++i) sum += shape[i] * q[i];
    out[row] = sum;
  }
  if (!correct) return {};
  // R is symmetric: the response of every surface dof to F_l is row (3 s_l + b) of R.
  const std::size_t s3 = 3U * model.surface_nodes.size();
  for (const NodeLoad& load : state.loads) {
    const std::int32_t s_l = model.surface_index[load.node];
    if (s_l < 0) continue;  // the runtime refuses such loads with static correction on
    for (std::size_t b = 0; b < 3; ++b) {
      const float f = load.force_n[b];
      if (f == 0.0F) continue;
      const float* row =
          model.residual_compliance.data() + (3U * static_cast<std::size_t>(s_l) + b) * s3;
      for (std::size_t k = 0; k < model.surface_nodes.size(); ++k) {
        float* u = out.data() + 3U * model.surface_nodes[k];
        u[0] += row[3 * k] * f;
        u[1] += row[3 * k + 1] * f;
        u[2] += row[3 * k + 2] * f;
      }
    }
  }
  return {};
}

core::Expected<void> reconstruct_tensor(ModelAssets& model, const ModelState& state,
                                        std::span<float> out) {
  const std::size_t n3 = 3U * model.node_count;
  if (out.size() < n3) return core::make_error("reconstruct: output shorter than 3n");
  std::fill(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n3), 0.0F);
  if (!model.tensor) return core::make_error("model '" + model.name + "' is not a tensor model");
  std::vector<model::TensorContact> contacts;
  contacts.reserve(state.contacts.size());
  for (const TensorContactState& c : state.contacts) {
    contacts.push_back(model::TensorContact{
        c.node, model::Vec3(c.displacement_m[0], c.displacement_m[1], c.displacement_m[2])});
  }
  if (const core::Status status = model.tensor->solve(contacts); !status) {
    return core::make_error("model '" + model.name + "': the streamed contacts do not solve (" +
                            std::string(core::to_string(status.code())) + ": " + status.detail() +
                            ")");
  }
  model.tensor->update_field();
  const std::span<const float> field = model.tensor->displacements();
  const std::span<const std::uint32_t> nodes = model.tensor->response_nodes();
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    std::copy_n(field.data() + 3 * j, 3, out.data() + 3U * nodes[j]);
  }
  return {};
}

}  // namespace trainer::viewer
