#include "imaging/io/async_sequence_writer.h"

#include <algorithm>
#include <exception>
#include <stdexcept>
#include <utility>

#include "imaging/io/sequence_writer.h"

namespace echoservo::imaging {
namespace {

std::size_t CheckedCapacity(std::size_t n) {
  if (n == 0) throw std::invalid_argument("volume recorder: the queue needs room for ≥ 1 volume");
  return n;
}

}  // namespace

AsyncSequenceWriter::AsyncSequenceWriter(std::filesystem::path header_path,
                                         std::size_t queue_capacity)
    : file_(std::make_unique<SequenceWriter>(std::move(header_path))),
      capacity_(CheckedCapacity(queue_capacity)) {
  sink_ = [this](const Volume& v) { file_->Append(v); };
  thread_ = std::thread([this] { Run(); });
}

AsyncSequenceWriter::AsyncSequenceWriter(Sink sink, std::size_t queue_capacity)
    : sink_(std::move(sink)), capacity_(CheckedCapacity(queue_capacity)) {
  if (!sink_) throw std::invalid_argument("volume recorder: no sink");
  thread_ = std::thread([this] { Run(); });
}

AsyncSequenceWriter::~AsyncSequenceWriter() {
  try {
    Close();
  } catch (...) {  // the error is in stats(); a destructor does not throw
  }
}

bool AsyncSequenceWriter::Submit(Volume volume) {
  {
    std::lock_guard lock(mutex_);
    ++stats_.submitted;
    if (closing_ || !stats_.error.empty() || queue_.size() >= capacity_) {
      ++stats_.dropped;
      return false;
    }
    queue_.push_back(std::move(volume));
    stats_.queue_high_water =
        std::max<std::uint64_t>(stats_.queue_high_water, queue_.size() + (writing_ ? 1 : 0));
  }
  cv_.notify_one();
  return true;
}

void AsyncSequenceWriter::Close() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  if (file_) {
    std::lock_guard lock(mutex_);
    if (stats_.written > 0) {
      try {
        file_->SyncData();
      } catch (const std::exception& e) {
        if (stats_.error.empty()) stats_.error = e.what();
      }
    }
  }
}

AsyncRecorderStats AsyncSequenceWriter::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::string AsyncSequenceWriter::SummaryJson() const {
  const AsyncRecorderStats s = stats();
  std::string error;  // JSON string escapes of the error text
  for (const char c : s.error) {
    if (c == '"' || c == '\\') {
      error += '\\';
      error += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      error += ' ';
    } else {
      error += c;
    }
  }
  return "{\"volumes_recorded\": " + std::to_string(s.written) +
         ", \"volumes_record_dropped\": " + std::to_string(s.dropped) +
         ", \"volumes_submitted\": " + std::to_string(s.submitted) +
         ", \"queue_volumes\": " + std::to_string(capacity_) +
         ", \"queue_high_water\": " + std::to_string(s.queue_high_water) +
         ", \"error\": " + (s.error.empty() ? std::string("null") : "\"" + error + "\"") + "}\n";
}

void AsyncSequenceWriter::Run() {
  std::unique_lock lock(mutex_);
  while (true) {
    cv_.wait(lock, [this] { return closing_ || !queue_.empty(); });
    if (queue_.empty()) return;  // closing, all written
    Volume v = std::move(queue_.front());
    queue_.pop_front();
    writing_ = true;
    lock.unlock();
    std::string error;
    try {
      sink_(v);
    } catch (const std::exception& e) {
      error = e.what();
    }
    lock.lock();
    writing_ = false;
    if (error.empty()) {
      ++stats_.written;
    } else {  // the recording stops: what waits is dropped, and so is what comes
      stats_.error = error;
      stats_.dropped += 1 + queue_.size();
      queue_.clear();
    }
  }
}

}  // namespace echoservo::imaging
