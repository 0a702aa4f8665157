// The sections of the GPIO and USB parts for people (one line per item and step) and as JSON.
#include <cstdio>
#include <string>

#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

std::string hil_report_upper(Outcome outcome) {
  switch (outcome) {
    case Outcome::pass: return "PASS";
    case Outcome::fail: return "FAIL";
    case Outcome::skip: return "SKIP";
  }
  return "?";
}

std::string hil_report_step(const StepResult& step) {
  return hil_report_upper(step.outcome) + "  " + step.id + "  " + step.title + ": " + step.reason +
         "\n";
}

nlohmann::json hil_report_step_json(const StepResult& step) {
  nlohmann::json figures = nlohmann::json::array();
  for (const Figure& f : step.figures) {
    figures.push_back({{"name", f.name}, {"value", f.value}, {"unit", f.unit}});
  }
  return {{"id", step.id},           {"title", step.title},     {"outcome", to_string(step.outcome)},
          {"reason", step.reason},   {"figures", figures},      {"details", step.details}};
}

}  // namespace

std::string format_scan(const ScanSection& section) {
  std::string out;
  if (section.found.empty()) out += section.part + ": nothing found\n";
  for (const ScanItem& item : section.found) {
    std::string props;
    for (const auto& [key, value] : item.properties.items()) {
      props += " " + key + "=" + (value.is_string() ? value.get<std::string>() : value.dump());
    }
    out += "found " + item.kind + " " + item.name + ":" + props + "\n";
  }
  for (const StepResult& step : section.comparison) out += hil_report_step(step);
  return out;
}

std::string format_check(const CheckSection& section) {
  std::string out;
  for (const StepResult& step : section.steps) out += hil_report_step(step);
  for (const Correction& c : section.corrections) {
    out += "CORRECT " + c.table + "." + c.key + ": " + c.old_value + " -> " + c.new_value + " (" +
           c.why + ")\n";
  }
  return out;
}

nlohmann::json to_json(const ScanSection& section) {
  nlohmann::json found = nlohmann::json::array();
  for (const ScanItem& item : section.found) {
    found.push_back({{"kind", item.kind}, {"name", item.name}, {"properties", item.properties}});
  }
  nlohmann::json steps = nlohmann::json::array();
  for (const StepResult& step : section.comparison) steps.push_back(hil_report_step_json(step));
  return {{"part", section.part}, {"found", found}, {"comparison", steps}};
}

nlohmann::json to_json(const CheckSection& section) {
  nlohmann::json steps = nlohmann::json::array();
  for (const StepResult& step : section.steps) steps.push_back(hil_report_step_json(step));
  nlohmann::json corrections = nlohmann::json::array();
  for (const Correction& c : section.corrections) {
    corrections.push_back({{"table", c.table}, {"instrument", c.instrument}, {"key", c.key},
                           {"old_value", c.old_value}, {"new_value", c.new_value}, {"why", c.why}});
  }
  return {{"part", section.part}, {"steps", steps}, {"corrections", corrections}};
}

}  // namespace trainer::hil
