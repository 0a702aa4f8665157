#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <string>

#include "trainer/record/cycle_record.hpp"

namespace trainer::record {
namespace {

std::string text_of(std::uint64_t v) {
  return std::to_string(v);
}
std::string text_of(float v) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  char out[64];
  std::snprintf(out, sizeof out, "%.9g (0x%08" PRIx32 ")", static_cast<double>(v), bits);
  return out;
}
std::string hex_of(std::uint64_t v) {
  char out[32];
  std::snprintf(out, sizeof out, "0x%016" PRIx64, v);
  return out;
}

bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

struct Differ {
  std::string found;
  void check(bool differs, const std::string& field, const std::string& recorded,
             const std::string& replayed) {
    if (found.empty() && differs)
      found = field + ": recorded " + recorded + ", replayed " + replayed;
  }
  void integer(const std::string& field, std::uint64_t a, std::uint64_t b) {
    check(a != b, field, text_of(a), text_of(b));
  }
  void real(const std::string& field, float a, float b) {
    check(!same_bits(a, b), field, text_of(a), text_of(b));
  }
  void vec(const std::string& field, const std::array<float, 3>& a, const std::array<float, 3>& b) {
    for (std::size_t k = 0; k < 3; ++k) real(field + "[" + std::to_string(k) + "]", a[k], b[k]);
  }
};

}  // namespace

std::string first_output_difference(const CycleRecord& recorded, const CycleRecord& replayed) {
  Differ d;
  d.integer("channel_count", recorded.channel_count, replayed.channel_count);
  d.integer("actuator_write_rc", recorded.actuator_write_rc, replayed.actuator_write_rc);
  d.integer("actuator_writes", recorded.actuator_writes, replayed.actuator_writes);
  const std::size_t channels = std::min<std::size_t>(recorded.channel_count, kMaxRecordChannels);
  for (std::size_t c = 0; c < channels; ++c) {
    const std::string name = "command[channel " + std::to_string(c) + "]";
    d.real(name + ".effort", recorded.commands[c].effort, replayed.commands[c].effort);
    d.integer(name + ".enable", recorded.commands[c].enable, replayed.commands[c].enable);
  }
  d.integer("digital_out_rc", recorded.digital_out_rc, replayed.digital_out_rc);
  d.integer("digital_out_writes", recorded.digital_out_writes, replayed.digital_out_writes);
  d.integer("digital_out_levels", recorded.digital_out_levels, replayed.digital_out_levels);
  d.integer("latched_faults", recorded.latched_faults, replayed.latched_faults);
  d.check(recorded.state_hash != replayed.state_hash, "state_hash", hex_of(recorded.state_hash),
          hex_of(replayed.state_hash));
  const DerivedSample& a = recorded.derived;
  const DerivedSample& b = replayed.derived;
  d.integer("derived.instrument_count", a.instrument_count, b.instrument_count);
  d.integer("derived.contact_model", static_cast<std::uint32_t>(a.contact_model),
            static_cast<std::uint32_t>(b.contact_model));
  d.real("derived.insertion_depth_m", a.insertion_depth_m, b.insertion_depth_m);
  for (std::size_t i = 0; i < kMaxRecordInstruments; ++i) {
    const std::string name = "derived.instrument[" + std::to_string(i) + "]";
    d.vec(name + ".tip_m", a.instruments[i].tip_m, b.instruments[i].tip_m);
    d.vec(name + ".tissue_force_n", a.instruments[i].tissue_force_n,
          b.instruments[i].tissue_force_n);
    d.vec(name + ".contact_point_m", a.instruments[i].contact_point_m,
          b.instruments[i].contact_point_m);
    d.real(name + ".grip_rad", a.instruments[i].grip_rad, b.instruments[i].grip_rad);
    d.integer(name + ".tissue_contact", a.instruments[i].tissue_contact,
              b.instruments[i].tissue_contact);
    d.integer(name + ".grasping", a.instruments[i].grasping, b.instruments[i].grasping);
  }
  return d.found;
}

}  // namespace trainer::record
