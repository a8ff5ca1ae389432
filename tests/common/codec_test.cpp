// The wire codec: every message round-trips through its two frames with the protocol version
// stamped; garbage (wrong frame counts, unknown types, oversized or malformed bodies) raises a
// DecodeError naming the cause and never crashes; fixed-point sums survive the wire bit for bit.
#include <gtest/gtest.h>

#include <google/protobuf/descriptor.h>

#include <algorithm>
#include <limits>
#include <random>
#include <set>

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/protocol/heartbeat.h"
#include "tests/support/tile_result_compare.h"

namespace rayfarm::protocol {
namespace {

using Kind = DecodeError::Kind;

Kind decode_error_kind(const net::Frames& frames) {
  try {
    decode(frames);
  } catch (const DecodeError& e) {
    EXPECT_FALSE(std::string(e.what()).empty());
    return e.kind();
  }
  ADD_FAILURE() << "decoded without error";
  return Kind::kMalformedBody;
}

TEST(Codec, HelloRoundTripsWithVersionStamped) {
  wire::Hello hello;
  hello.set_role(wire::ROLE_WORKER);
  hello.set_name("w1");
  hello.set_threads(8);
  hello.set_build("test");
  const net::Frames frames = encode(hello);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0], "rayfarm.wire.Hello");

  const Decoded d = decode(frames);
  EXPECT_EQ(d.type, "rayfarm.wire.Hello");
  EXPECT_EQ(d.version, kProtocolVersion);
  EXPECT_TRUE(d.version_ok());
  const auto* back = d.as<wire::Hello>();
  ASSERT_NE(back, nullptr);
  EXPECT_EQ(back->name(), "w1");
  EXPECT_EQ(back->threads(), 8u);
  EXPECT_EQ(back->role(), wire::ROLE_WORKER);
  EXPECT_EQ(d.as<wire::Welcome>(), nullptr);
}

TEST(Codec, AnotherVersionIsDecodedAndFlagged) {
  const uint32_t other = kProtocolVersion + 1;
  const Decoded d = decode(encode(wire::Hello{}, other));
  EXPECT_EQ(d.version, other);
  EXPECT_FALSE(d.version_ok());
  EXPECT_NE(d.as<wire::Hello>(), nullptr);
}

TEST(Codec, EveryTopLevelMessageCarriesTheVersion) {
  const auto* file = wire::Hello::descriptor()->file();
  const std::set<std::string> building_blocks{"RenderSettings", "Rect",          "BundleFile",
                                              "Bundle",         "JobOverrides",  "WorkerInfo",
                                              "FrameList",      "SequenceFrame", "UnitInfo",
                                              "JobWorkerShare", "JobLogLine"};
  int wire_messages = 0;
  for (int i = 0; i < file->message_type_count(); ++i) {
    const auto* d = file->message_type(i);
    if (building_blocks.count(d->name())) {
      EXPECT_FALSE(is_wire_message(d)) << d->name();
      continue;
    }
    EXPECT_TRUE(is_wire_message(d)) << d->full_name() << " lacks field 1 protocol_version";
    ++wire_messages;
  }
  EXPECT_GE(wire_messages, 20);
}

TEST(Codec, EveryErrorCodeRoundTripsWithItsMessage) {
  const auto* codes = wire::Error::Code_descriptor();
  ASSERT_GE(codes->value_count(), 9);
  for (int i = 0; i < codes->value_count(); ++i) {
    const auto code = static_cast<wire::Error::Code>(codes->value(i)->number());
    wire::Error error;
    error.set_code(code);
    error.set_message("cause " + codes->value(i)->name());
    error.set_job_id("j0007");
    const Decoded d = decode(encode(error));
    const auto* back = d.as<wire::Error>();
    ASSERT_NE(back, nullptr) << codes->value(i)->name();
    EXPECT_EQ(back->code(), code) << codes->value(i)->name();
    EXPECT_EQ(back->message(), "cause " + codes->value(i)->name());
    EXPECT_EQ(back->job_id(), "j0007");

    wire::SubmitReply refused;
    refused.set_code(code);
    refused.set_error("refused: " + codes->value(i)->name());
    const Decoded r = decode(encode(refused));
    ASSERT_NE(r.as<wire::SubmitReply>(), nullptr);
    EXPECT_EQ(r.as<wire::SubmitReply>()->code(), code) << codes->value(i)->name();
    EXPECT_EQ(r.as<wire::SubmitReply>()->error(), "refused: " + codes->value(i)->name());
  }
  // An Error without a code reads as CODE_UNSPECIFIED, which no peer acts on.
  EXPECT_EQ(decode(encode(wire::Error{})).as<wire::Error>()->code(), wire::Error::CODE_UNSPECIFIED);
}

TEST(Codec, WorkUnitAndResultRoundTrip) {
  wire::WorkUnit unit;
  unit.set_job_id("j0001");
  unit.set_unit_id(12345678901ull);
  *unit.mutable_tile() = rect_to_wire({64, 0, 128, 64});
  unit.set_sample_begin(16);
  unit.set_sample_end(32);
  *unit.mutable_settings() = settings_to_wire(RenderSettings{256, 8, IntegratorType::kNee, 42});
  unit.set_bundle_hash(std::string(64, 'a'));
  unit.set_scene_path("box/scene.json");
  const Decoded d = decode(encode(unit));
  const auto* back = d.as<wire::WorkUnit>();
  ASSERT_NE(back, nullptr);
  EXPECT_EQ(back->unit_id(), 12345678901ull);
  EXPECT_EQ(rect_from_wire(back->tile()), (TileRect{64, 0, 128, 64}));
  const RenderSettings s = settings_from_wire(back->settings());
  EXPECT_EQ(s.spp, 256u);
  EXPECT_EQ(s.max_depth, 8u);
  EXPECT_EQ(s.integrator, IntegratorType::kNee);
  EXPECT_EQ(s.seed, 42u);
}

/// The packed size of `values`, counted independently of pack_fixed: 7 bits a byte of the
/// zigzag form, at least one byte.
size_t packed_size(const std::vector<Fixed>& values) {
  size_t bytes = 0;
  for (const Fixed v : values) {
    const UFixed z = v < 0 ? (static_cast<UFixed>(-(v + 1)) << 1) | 1 : static_cast<UFixed>(v) << 1;
    int bits = 0;
    for (UFixed x = z; x != 0; x >>= 1) ++bits;
    bytes += std::max(1, (bits + 6) / 7);
  }
  return bytes;
}

TEST(Codec, FixedPointSumsSurviveTheWireBitForBit) {
  TileResult r({0, 0, 3, 2}, {0, 4});
  std::mt19937_64 rng(1);
  for (size_t i = 0; i < r.sum.size(); ++i) {
    r.sum[i] = fixed_from_parts(rng(), static_cast<int64_t>(rng()));
    r.sum_sq[i] = to_fixed(std::ldexp(static_cast<double>(rng() % 1000), static_cast<int>(i) - 8));
  }
  r.sum[0] = std::numeric_limits<Fixed>::min();
  r.sum[1] = -1;
  r.sum[2] = std::numeric_limits<Fixed>::max();
  r.nonfinite = 3;
  r.rays = 99;
  const Decoded d = decode(encode(result_to_wire("j0002", 7, r, 0.25)));
  const auto* wire_result = d.as<wire::UnitResult>();
  ASSERT_NE(wire_result, nullptr);
  EXPECT_EQ(wire_result->sum().size(), packed_size(r.sum));
  const TileResult back = result_from_wire(*wire_result);
  EXPECT_TRUE(back.well_formed());
  testing::expect_same_result(back, r);
}

TEST(Codec, FixedPointValuesAreZigzagVarints) {
  // 0, -1, 1, -2, 63, -64 fit one byte; 64 takes two (zigzag 128 = 0x80 0x01).
  EXPECT_EQ(pack_fixed({0, -1, 1, -2, 63, -64}), std::string("\x00\x01\x02\x03\x7e\x7f", 6));
  EXPECT_EQ(pack_fixed({64}), std::string("\x80\x01", 2));
  // The extremes take all 19 bytes, the last holding bits 126 and 127.
  const std::string max = pack_fixed({std::numeric_limits<Fixed>::max()});
  ASSERT_EQ(max.size(), kMaxFixedWireBytes);
  EXPECT_EQ(static_cast<unsigned char>(max.back()), 0x03);
  EXPECT_EQ(pack_fixed({std::numeric_limits<Fixed>::min()}).size(), kMaxFixedWireBytes);
  // A typical sum: 256 samples of about 0.5 is 2^47, 7 bytes instead of 16.
  EXPECT_EQ(pack_fixed({to_fixed(128.3)}).size(), 7u);
}

TEST(Codec, FixedPointValuesOfEveryWidthAndSignComeBackExactly) {
  // Magnitudes of every width from 0 to 126 bits (and the extremes), both signs, in one run of
  // bytes (the 8-byte fast path and the byte-by-byte one both read them), then each alone (a value
  // of 8 bytes or more then has exactly its own bytes left).
  std::mt19937_64 rng(7);
  std::vector<Fixed> values;
  for (int bits = 0; bits < 128; ++bits) {
    for (int rep = 0; rep < 4; ++rep) {
      UFixed x = (static_cast<UFixed>(rng()) << 64) | rng();
      x = bits == 0 ? 0 : (x >> (128 - bits)) | (UFixed{1} << (bits - 1));
      const Fixed v = static_cast<Fixed>(x >> 1);  // fits a positive Fixed
      values.push_back(rep % 2 ? -v : v);
      values.push_back(rep % 2 ? -v - 1 : v + 1);
    }
  }
  values.push_back(std::numeric_limits<Fixed>::min());
  values.push_back(std::numeric_limits<Fixed>::max());
  const std::string bytes = pack_fixed(values);
  EXPECT_EQ(bytes.size(), packed_size(values));
  EXPECT_TRUE(unpack_fixed(bytes, values.size()) == values);
  for (const Fixed v : values) {
    ASSERT_TRUE(unpack_fixed(pack_fixed({v}), 1) == std::vector<Fixed>{v});
  }
}

TEST(Codec, MalformedFixedPointBytesAreProtocolErrorsNamingTheFault) {
  const auto fails_with = [](std::string_view bytes, size_t count, const std::string& words) {
    try {
      unpack_fixed(bytes, count);
      ADD_FAILURE() << "accepted " << bytes.size() << " bytes as " << count << " values";
    } catch (const ProtocolError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  const std::string two = pack_fixed({5, to_fixed(1e6)});
  EXPECT_EQ(unpack_fixed(two, 2), (std::vector<Fixed>{5, to_fixed(1e6)}));
  fails_with(two, 3, "cut short");               // the third value is missing
  fails_with(two + "\x01", 2, "1 bytes after");  // trailing garbage
  fails_with(two.substr(0, two.size() - 1), 2, "cut short");
  fails_with(std::string(18, '\xff') + "\x04", 1, "wider than 128 bits");
  fails_with(std::string(20, '\x00'), 1, "got 20 bytes");  // more than any value takes
  // A claim of a huge tile with a few bytes allocates nothing.
  fails_with(std::string_view("\x00", 1), size_t{1} << 40, "got 1 bytes");
}

TEST(Codec, InconsistentResultsAreProtocolErrors) {
  TileResult r({0, 0, 2, 2}, {0, 1});
  wire::UnitResult w = result_to_wire("j", 0, r, 0.0);
  w.mutable_tile()->set_x1(3);  // sums are for 4 pixels, the tile claims 6
  EXPECT_THROW(result_from_wire(w), ProtocolError);
  w = result_to_wire("j", 0, r, 0.0);
  w.set_sample_end(0);
  EXPECT_THROW(result_from_wire(w), ProtocolError);
  w = result_to_wire("j", 0, r, 0.0);
  w.mutable_tile()->set_x0(5);  // empty rectangle
  EXPECT_THROW(result_from_wire(w), ProtocolError);
  w = result_to_wire("j", 0, r, 0.0);
  w.mutable_tile()->set_x1(4000000000u);  // absurdly wide: rejected before any allocation
  w.mutable_tile()->set_y1(4000000000u);
  EXPECT_THROW(result_from_wire(w), ProtocolError);
}

TEST(Codec, BadIntegratorAndZeroSppAreRejected) {
  wire::RenderSettings s;
  s.set_spp(1);
  EXPECT_THROW(settings_from_wire(s), ProtocolError);  // unspecified integrator
  s.set_integrator(static_cast<wire::Integrator>(99));
  EXPECT_THROW(settings_from_wire(s), ProtocolError);
  s.set_integrator(wire::INTEGRATOR_MIS);
  s.set_spp(0);
  EXPECT_THROW(settings_from_wire(s), ProtocolError);
}

TEST(Codec, WrongFrameCountsAreRejected) {
  EXPECT_EQ(decode_error_kind({}), Kind::kFrameCount);
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.Hello"}), Kind::kFrameCount);
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.Hello", "", ""}), Kind::kFrameCount);
}

TEST(Codec, UnknownAndNonWireTypesAreRejected) {
  EXPECT_EQ(decode_error_kind({"", ""}), Kind::kUnknownType);
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.NoSuchMessage", ""}), Kind::kUnknownType);
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.Rect", ""}), Kind::kUnknownType);  // not sent alone
  EXPECT_EQ(decode_error_kind({"google.protobuf.FileDescriptorProto", ""}), Kind::kUnknownType);
  EXPECT_EQ(decode_error_kind({std::string("rayfarm.wire.Hello\0x", 20), ""}), Kind::kUnknownType);
  EXPECT_EQ(decode_error_kind({std::string(1000, 'x'), ""}), Kind::kTooLarge);
}

TEST(Codec, MalformedBodiesAreRejected) {
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.Hello", "\xff\xff\xff\xff"}), Kind::kMalformedBody);
  // A truncated length-delimited field.
  wire::Hello hello;
  hello.set_name(std::string(100, 'n'));
  std::string body = encode(hello)[1];
  body.resize(body.size() - 10);
  EXPECT_EQ(decode_error_kind({"rayfarm.wire.Hello", body}), Kind::kMalformedBody);
}

TEST(Codec, RandomBytesNeverCrash) {
  std::mt19937 rng(7);
  const auto* file = wire::Hello::descriptor()->file();
  int rejected = 0;
  for (int i = 0; i < 2000; ++i) {
    std::string body(rng() % 64, '\0');
    for (char& c : body) c = static_cast<char>(rng());
    const std::string type =
        file->message_type(static_cast<int>(rng() % file->message_type_count()))->full_name();
    try {
      const Decoded d = decode({type, body});
      EXPECT_EQ(d.type, type);
    } catch (const DecodeError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
}

TEST(Codec, PeerTextIsMadeSafeForOneLogLine) {
  EXPECT_EQ(printable("worker-1"), "worker-1");
  EXPECT_EQ(printable("a\nb\"c\\d\x01"), "a?b?c?d?");
  EXPECT_EQ(printable(std::string(100, 'x'), 8), "xxxxxxxx...");
}

TEST(Heartbeat, DefaultsAreConsistent) {
  const HeartbeatOptions o;
  EXPECT_EQ(o.expiry(), kHeartbeatInterval * kHeartbeatLiveness);
  EXPECT_LE(o.reconnect_min, o.reconnect_max);
  EXPECT_GE(kHeartbeatLiveness, 2);
}

}  // namespace
}  // namespace rayfarm::protocol
