// The device file's [gpio] and [telemetry] tables (device_io_tables.cpp), read by
// load_device.cpp. Errors go through the TableReader / ErrorSink as every table's do.
#pragma once

#include "table_reader.hpp"
#include "trainer/config/device.hpp"

namespace trainer::config::detail {

// [gpio]: the lines of the digital input and output words.
GpioConfig read_gpio(TableReader& table, const DigitalConfig& digital, ErrorSink& errors);
// Every wired [digital] bit needs its GPIO line.
void check_gpio_wiring(const DeviceConfig& config, TableReader& digital_table, ErrorSink& errors);
// [telemetry]: optional; when present and enabled the destination is required.
TelemetryConfig read_telemetry(TableReader& table);

}  // namespace trainer::config::detail
