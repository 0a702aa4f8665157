// The trainee metrics as the telemetry stream carries them (wire format 1.1, section 18): the
// session's SessionResult so far (rt/metrics) in the frame's fixed, float32 form, for the
// graphics host's session panel (docs/telemetry.md, docs/metrics.md). Non-RT (supervisor).
#pragma once

#include "trainer/metrics/session_metrics.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::app {

telemetry::SessionMetrics stream_metrics(const metrics::SessionResult& result) noexcept;

}  // namespace trainer::app
