// Fault SPECs (the program's --fault and stdin syntax): parsed, defaulted, refused by name, and
// formatted back canonically; the events log's ring and JSON lines.
#include <gtest/gtest.h>

#include "trainer/hal_simdrive/events.hpp"
#include "trainer/hal_simdrive/fault.hpp"

namespace trainer::hal::simdrive {
namespace {

FaultSpec parsed(const char* text) {
  auto spec = parse_fault_spec(text);
  EXPECT_TRUE(spec) << text << ": " << (spec ? "" : spec.error().message);
  return spec ? *spec : FaultSpec{};
}

std::string refusal(const char* text) {
  auto spec = parse_fault_spec(text);
  EXPECT_FALSE(spec) << text << " was accepted";
  return spec ? std::string() : spec.error().message;
}

TEST(FaultSpec, TheExamplesOfTheBriefParse) {
  FaultSpec spec = parsed("emcy:node=3,at_sync=500,code=0x2310");
  EXPECT_EQ(spec.kind, FaultKind::emcy);
  EXPECT_EQ(spec.node_id, 3);
  EXPECT_EQ(spec.at_sync, 500U);
  EXPECT_EQ(spec.code, 0x2310);
  spec = parsed("silent:node=2,at_s=1.5");
  EXPECT_EQ(spec.kind, FaultKind::silent);
  EXPECT_EQ(spec.at_ns, 1'500'000'000);
  EXPECT_EQ(spec.count, 0U) << "until cleared";
  spec = parsed("drop:node=1,at_sync=100,count=5");
  EXPECT_EQ(spec.count, 5U);
  spec = parsed("bus_off:at_sync=800");
  EXPECT_EQ(spec.kind, FaultKind::bus_off);
  EXPECT_EQ(spec.node_id, 0);
  EXPECT_TRUE(spec.scheduled());
  spec = parsed("  delay:node=4,ms=12  \n");
  EXPECT_EQ(spec.delay_ns, 12'000'000);
  EXPECT_FALSE(spec.scheduled());
  spec = parsed("corrupt:node=5,mode=bits,byte=7,mask=0x81");
  EXPECT_EQ(spec.corrupt_mode, CorruptMode::bits);
  EXPECT_EQ(spec.corrupt_byte, 7);
  EXPECT_EQ(spec.corrupt_mask, 0x81);
  EXPECT_EQ(spec.count, 1U) << "a corruption lasts one SYNC unless told";
  EXPECT_EQ(parsed("lost_sync:node=1").count, 1U);
  EXPECT_EQ(parsed("encoder_jump:node=1,counts=-4096").counts, -4096);
  EXPECT_DOUBLE_EQ(parsed("push:node=2,move=-0.05,count=300").move, -0.05);
  EXPECT_EQ(parsed("push:node=2,move=0.1").count, 0U);
  EXPECT_EQ(parsed("emcy:node=9").code, 0x2310) << "continuous over-current by default";
  EXPECT_EQ(parsed("clear").node_id, 0);
  EXPECT_EQ(parsed("reboot:node=127").node_id, 127);
}

TEST(FaultSpec, MistakesAreRefusedNamingTheKeyAndWhatWasExpected) {
  EXPECT_NE(refusal("explode:node=1").find("unknown kind 'explode'"), std::string::npos);
  EXPECT_NE(refusal("emcy").find("node=N missing"), std::string::npos);
  EXPECT_NE(refusal("emcy:node=0").find("node = '0'"), std::string::npos);
  EXPECT_NE(refusal("emcy:node=128").find("1..127"), std::string::npos);
  EXPECT_NE(refusal("bus_off:node=2").find("no node key"), std::string::npos);
  EXPECT_NE(refusal("delay:node=2").find("ms=D missing"), std::string::npos);
  EXPECT_NE(refusal("drop:node=2,ms=3").find("unknown key 'ms'"), std::string::npos);
  EXPECT_NE(refusal("emcy:node=2,code=0").find("0x0001..0xFFFF"), std::string::npos);
  EXPECT_NE(refusal("encoder_jump:node=2").find("counts=N missing"), std::string::npos);
  EXPECT_NE(refusal("push:node=2").find("move=D missing"), std::string::npos);
  EXPECT_NE(refusal("push:node=2,move=0").find("expected a non-zero joint displacement"),
            std::string::npos);
  EXPECT_NE(refusal("drop:node=2,at_sync=0").find("SYNC count >= 1"), std::string::npos);
  EXPECT_NE(refusal("drop:node=2,at_s=-1").find("seconds"), std::string::npos);
  EXPECT_NE(refusal("drop:node=2,at_s=1,at_sync=3").find("both"), std::string::npos);
  EXPECT_NE(refusal("corrupt:node=2,mode=garble").find("length or bits"), std::string::npos);
  EXPECT_NE(refusal("drop:node").find("KEY=VALUE"), std::string::npos);
  EXPECT_NE(refusal("drop:node=2x").find("node = '2x'"), std::string::npos);
}

TEST(FaultSpec, FormattingGivesTheCanonicalSpecBack) {
  for (const char* text :
       {"emcy:node=3,at_sync=500,code=0x2310", "silent:node=2,at_s=1.500", "drop:node=1,count=5",
        "bus_off:at_sync=800", "delay:node=4,ms=12", "corrupt:node=5,mode=length",
        "corrupt:node=5,count=3,mode=bits,byte=7,mask=0x81", "encoder_jump:node=1,counts=-4096",
        "push:node=2,count=300,move=-0.05",
        "lost_sync:node=1,count=2", "reboot:node=6", "clear", "clear:node=2"}) {
    EXPECT_EQ(format_fault_spec(parsed(text)), text);
  }
  // The no-heap form cuts at the buffer.
  std::array<char, 8> small{};
  EXPECT_EQ(format_fault_spec(parsed("encoder_jump:node=1,counts=-4096"), small), 7U);
  EXPECT_STREQ(small.data(), "encoder");
}

TEST(EventLog, KeepsTheOldestWhenFullAndCountsTheRest) {
  EventLog log(3);
  for (std::uint8_t node = 1; node <= 5; ++node) {
    DriveEvent event;
    event.node = node;
    EXPECT_EQ(log.push(event), node <= 3);
  }
  EXPECT_EQ(log.dropped(), 2U);
  EXPECT_EQ(log.recorded(), 5U);
  DriveEvent out;
  ASSERT_TRUE(log.pop(out));
  EXPECT_EQ(out.node, 1);
  EXPECT_EQ(log.snapshot().size(), 2U);
  EXPECT_EQ(log.snapshot()[0].node, 2);
}

TEST(EventLog, EventsAreOneJsonObjectPerLine) {
  DriveEvent event;
  event.t_ns = 123456789;
  event.sync = 42;
  event.node = 3;
  event.kind = EventKind::power_state;
  event.a = 4;  // operation enabled
  event.b = 1;  // switch on disabled
  event.cause = "master heartbeat \"lost\"";
  EXPECT_EQ(to_json(event),
            "{\"t_ns\":123456789,\"sync\":42,\"node\":3,\"event\":\"power_state\",\"from\":"
            "\"operation enabled\","
            "\"to\":\"switch on disabled\",\"cause\":\"master heartbeat \\\"lost\\\"\"}");
  DriveEvent emcy;
  emcy.kind = EventKind::emcy_sent;
  emcy.node = 2;
  emcy.a = 0x2310;
  emcy.b = 0x03;
  const std::string json = to_json(emcy);
  EXPECT_NE(json.find("\"code\":\"0x2310\",\"register\":\"0x03\",\"meaning\":\""),
            std::string::npos)
      << json;
  DriveEvent fault;
  fault.kind = EventKind::fault_injected;
  const char text[] = "drop:node=1,count=5";
  std::copy(std::begin(text), std::end(text), fault.text.begin());
  EXPECT_NE(to_json(fault).find("\"fault\":\"drop:node=1,count=5\""), std::string::npos);
  DriveEvent nmt;
  nmt.kind = EventKind::nmt_state;
  nmt.a = 0x7F;
  nmt.b = 0x05;
  EXPECT_NE(to_json(nmt).find("\"from\":\"pre-operational\",\"to\":\"operational\""),
            std::string::npos);
}

}  // namespace
}  // namespace trainer::hal::simdrive
