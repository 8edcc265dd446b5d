// OpenIGTLink ingest benchmark: CRC-64 throughput (libOpenIGTLink's byte-wise crc64 vs the
// slice-by-8 one), IMAGE encode cost, and validated loopback ingest of 160×148×208 uint8
// volumes (target ≥ 100 vol/s) with latency p50/p99 (send-time stamps, same clock), once
// with each CRC on the sending side. Binary: build/bin/echoservo_ingest_bench [frames].
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/phantom_source.h"

namespace igtl = echoservo::imaging::openigtlink;
using Clock = std::chrono::steady_clock;

namespace {

template <typename F>
double TimeMs(int reps, F f) {
  const auto t0 = Clock::now();
  for (int r = 0; r < reps; ++r) f();
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count() / reps;
}

void Ingest(const char* label, bool libigtl_crc, int frames) {
  igtl::PhantomOptions po;
  po.rate_hz = 0;
  po.frame_count = frames;
  igtl::PhantomSource source(po);
  igtl::ImageServerOptions so;
  so.rate_hz = 0.0;
  so.timestamps = igtl::ImageServerOptions::Timestamps::kSendTime;
  so.encode.libigtl_crc = libigtl_crc;
  igtl::ImageServer server(source, so);
  server.Start();
  igtl::IngestOptions io;
  io.port = server.port();
  io.queue_capacity = 4;
  igtl::IngestClient client(io);
  client.Start();
  std::int64_t consumed = 0;
  const auto t0 = Clock::now();
  Clock::time_point first{}, last{};
  while (consumed < frames) {
    auto f = client.NextFrame(5.0);
    if (!f) break;
    last = Clock::now();
    if (consumed == 0) first = last;
    ++consumed;
  }
  const double total_s = std::chrono::duration<double>(last - t0).count();
  const double steady_s = std::chrono::duration<double>(last - first).count();
  server.Stop();
  client.Stop();
  const auto s = client.stats();
  const auto ss = server.stats();
  std::printf(
      "%-22s frames %lld accepted %lld rejected %lld dropped %lld | %.1f vol/s (%.1f after the "
      "first) "
      "%.0f MB/s | latency ms p50 %.2f p99 %.2f | receive ms p50 %.2f p99 %.2f | encode %.2f "
      "ms/frame\n",
      label, static_cast<long long>(consumed), static_cast<long long>(s.frames),
      static_cast<long long>(s.rejected), static_cast<long long>(s.dropped),
      static_cast<double>(consumed) / total_s, static_cast<double>(consumed - 1) / steady_s,
      static_cast<double>(s.bytes) / total_s / 1e6, s.latency.p50_ms, s.latency.p99_ms,
      s.receive.p50_ms, s.receive.p99_ms, ss.encode_ms_mean);
}

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 300;
  igtl::PhantomSource phantom;
  const auto frame = phantom.Next();
  const auto& v = frame->volume;
  const auto voxels = v.voxels();
  std::printf("volume %dx%dx%d uint8 = %zu bytes\n", v.dims().x(), v.dims().y(), v.dims().z(),
              voxels.size());

  std::uint64_t sink = 0;
  const double lib_ms = TimeMs(10, [&] { sink ^= igtl::Crc64Ecma182LibIgtl(voxels); });
  const double fast_ms = TimeMs(30, [&] { sink ^= igtl::Crc64Ecma182(voxels); });
  const double gb = static_cast<double>(voxels.size()) / 1e9;
  std::printf("CRC-64 libOpenIGTLink crc64: %.2f ms/volume  %.2f GB/s\n", lib_ms,
              gb / (lib_ms / 1e3));
  std::printf("CRC-64 slice-by-8:           %.2f ms/volume  %.2f GB/s  (x%.1f)  [same value: %s]\n",
              fast_ms, gb / (fast_ms / 1e3), lib_ms / fast_ms,
              igtl::Crc64Ecma182(voxels) == igtl::Crc64Ecma182LibIgtl(voxels) ? "yes" : "NO");

  std::vector<std::uint8_t> buffer;
  const double enc_ms = TimeMs(30, [&] { igtl::EncodeImage(v, {}, buffer); });
  const double enc_lib_ms = TimeMs(10, [&] { sink ^= igtl::EncodeImageLibIgtl(v).size(); });
  igtl::EncodeImage(v, {}, buffer);
  const double dec_ms = TimeMs(30, [&] { sink ^= igtl::DecodeMessage(buffer, {}).header.crc; });
  std::printf(
      "encode: echoservo %.2f ms, igtl::ImageMessage::Pack %.2f ms; decode+validate %.2f ms\n",
      enc_ms, enc_lib_ms, dec_ms);

  Ingest("loopback, slice-by-8", false, frames);
  Ingest("loopback, libigtl crc", true, frames / 2);
  return sink == 42 ? 1 : 0;
}
