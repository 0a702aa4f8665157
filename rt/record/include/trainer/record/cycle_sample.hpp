// The trainee-metric sample of one recorded cycle: a CycleRecord's derived block (with its
// cycle index and latched faults) as rt/metrics' CycleSample, so metrics are computed from a
// recording without a replay (docs/recording.md, docs/metrics.md). The derived block holds the
// same fields in the same order.
#pragma once

#include <cstring>

#include "trainer/metrics/cycle_sample.hpp"
#include "trainer/record/cycle_record.hpp"

namespace trainer::record {

static_assert(sizeof(DerivedInstrument) == sizeof(metrics::InstrumentSample));
static_assert(kMaxRecordInstruments == metrics::kMaxSampleInstruments);

inline metrics::CycleSample cycle_sample_of(const CycleRecord& record) noexcept {
  metrics::CycleSample sample;
  sample.cycle = record.cycle_index;
  sample.time_ns = record.derived.time_ns;
  sample.latched_faults = record.latched_faults;
  sample.instrument_count = record.derived.instrument_count;
  for (std::size_t i = 0; i < kMaxRecordInstruments; ++i) {
    const DerivedInstrument& in = record.derived.instruments[i];
    metrics::InstrumentSample& out = sample.instruments[i];
    out.tip_m = in.tip_m;
    out.tissue_force_n = in.tissue_force_n;
    out.contact_point_m = in.contact_point_m;
    out.grip_rad = in.grip_rad;
    out.tissue_contact = in.tissue_contact;
    out.grasping = in.grasping;
  }
  sample.insertion_depth_m = record.derived.insertion_depth_m;
  sample.contact_model = record.derived.contact_model;
  return sample;
}

}  // namespace trainer::record
