// Costs on the F/T path that must stay far below the 7 kHz sample period
// (143 us): decoding one RDT record, encoding one (the simulated box), and
// one step of the depth-based contact model (the box calls it per sample).
#include <random>

#include "benchmark/benchmark.h"
#include "services/robot/netft/rdt_protocol.h"
#include "services/sim/contact_force.h"

namespace {

using bitewise::netft::DecodeRdtRecord;
using bitewise::netft::EncodeRdtRecord;
using bitewise::netft::RdtRecord;

void BM_DecodeRdtRecord(benchmark::State& state) {
  RdtRecord record;
  record.rdt_sequence = 12345;
  record.counts = {1, -2, 3000000, -400000, 5, 6};
  const auto bytes = EncodeRdtRecord(record);
  for (auto _ : state) {
    auto decoded = DecodeRdtRecord(bytes);
    benchmark::DoNotOptimize(decoded);
  }
}
BENCHMARK(BM_DecodeRdtRecord);

void BM_EncodeRdtRecord(benchmark::State& state) {
  RdtRecord record;
  record.counts = {1, -2, 3000000, -400000, 5, 6};
  for (auto _ : state) {
    ++record.rdt_sequence;
    auto bytes = EncodeRdtRecord(record);
    benchmark::DoNotOptimize(bytes);
  }
}
BENCHMARK(BM_EncodeRdtRecord);

void BM_ItemContactUpdate(benchmark::State& state) {
  std::mt19937_64 rng(1);
  const auto profile = bitewise::sim::ForceProfile::Sample(
      bitewise::sim::HapticCategory::kHardSkin, rng);
  bitewise::sim::ItemContact contact(profile, {});
  double depth_m = 0.0;
  for (auto _ : state) {
    depth_m += 1e-7;
    auto w = contact.Update(depth_m);
    benchmark::DoNotOptimize(w);
  }
}
BENCHMARK(BM_ItemContactUpdate);

}  // namespace

BENCHMARK_MAIN();
