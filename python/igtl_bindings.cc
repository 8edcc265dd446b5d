// The OpenIGTLink ingest client (imaging/igtl/ingest.h) in Python: IMAGE messages from any
// OpenIGTLink server (a scanner, PLUS, `echoservo scanner`) as Volumes, validated as the live
// tracker validates them, with the client's counters.
#include <pybind11/stl.h>

#include <memory>
#include <string>

#include "imaging/igtl/ingest.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

namespace igtl = imaging::openigtlink;

py::dict Summary(const igtl::LatencySummary& s) {
  py::dict d;
  d["count"] = s.count;
  d["p50_ms"] = s.p50_ms;
  d["p99_ms"] = s.p99_ms;
  d["max_ms"] = s.max_ms;
  d["mean_ms"] = s.mean_ms;
  return d;
}

py::dict StatsDict(const igtl::IngestStats& s) {
  py::dict d;
  d["frames"] = s.frames;
  d["rejected"] = s.rejected;
  d["rejected_by_reason"] = s.rejected_by_reason;
  d["skipped"] = s.skipped;
  d["skipped_by_type"] = s.skipped_by_type;
  d["dropped"] = s.dropped;
  d["delivered"] = s.delivered;
  d["connections"] = s.connections;
  d["connect_failures"] = s.connect_failures;
  d["last_connect_error"] = s.last_connect_error;
  d["bytes"] = s.bytes;
  d["latency"] = Summary(s.latency);
  d["receive"] = Summary(s.receive);
  d["elapsed_s"] = s.elapsed_s;
  return d;
}

}  // namespace

void RegisterIgtl(py::module_& m) {
  py::class_<igtl::IngestClient>(
      m, "IgtlClient",
      "OpenIGTLink ingest client: connects to HOST:PORT, validates every message, queues the\n"
      "accepted IMAGE frames (the oldest dropped when full) and reconnects with backoff\n"
      "(docs/openigtlink.md). Use as a context manager, or start() ... stop().")
      .def(py::init([](const std::string& host, int port, std::size_t queue_capacity,
                       int max_connect_failures, int connect_timeout_ms) {
             if (port < 1 || port > 65535)
               throw py::value_error("port: expected 1-65535, got " + std::to_string(port));
             igtl::IngestOptions o;
             o.host = host;
             o.port = port;
             o.queue_capacity = queue_capacity;
             o.max_connect_failures = max_connect_failures;
             o.connect_timeout_ms = connect_timeout_ms;
             return std::make_unique<igtl::IngestClient>(o);
           }),
           py::arg("host") = "127.0.0.1", py::arg("port"), py::arg("queue_capacity") = 4,
           py::arg("max_connect_failures") = -1, py::arg("connect_timeout_ms") = 1000,
           "host, port: the server; queue_capacity: frames kept (>= 1); max_connect_failures:\n"
           "consecutive failed connects before giving up (< 0: never).")
      .def("start", &igtl::IngestClient::Start, "start the receive thread")
      .def("stop", &igtl::IngestClient::Stop, py::call_guard<py::gil_scoped_release>(),
           "close the connection (next() then returns None); idempotent")
      .def(
          "next",
          [](igtl::IngestClient& c, double timeout_s) -> py::object {
            if (!(timeout_s >= 0)) throw py::value_error("timeout_s: expected >= 0");
            std::optional<igtl::IngestedFrame> f;
            {
              py::gil_scoped_release release;
              f = c.NextFrame(timeout_s);
            }
            if (!f) return py::none();
            py::dict d;
            d["volume"] = std::make_shared<imaging::Volume>(std::move(f->frame.volume));
            d["device_name"] = f->device_name;
            d["arrival_s"] = f->arrival_s;
            d["receive_ms"] = f->receive_ms;
            d["latency_ms"] =
                f->latency_ms ? py::object(py::float_(*f->latency_ms)) : py::object(py::none());
            return d;
          },
          py::arg("timeout_s") = 1.0,
          "The oldest queued frame, waiting up to timeout_s: a dict with 'volume' (Volume,\n"
          "timestamp_s = the message's), 'device_name', 'arrival_s' (Unix time), 'receive_ms',\n"
          "'latency_ms' (None unless the clocks are shared); None on timeout or after stop().")
      .def_property_readonly("ended", &igtl::IngestClient::ended, "stopped, or gave up connecting")
      .def(
          "stats", [](const igtl::IngestClient& c) { return StatsDict(c.stats()); },
          "frames accepted, rejected (by reason), skipped, dropped, delivered, connections, "
          "bytes,\n"
          "latency and receive-time summaries")
      .def(
          "__enter__",
          [](igtl::IngestClient& c) -> igtl::IngestClient& {
            c.Start();
            return c;
          },
          py::return_value_policy::reference)
      .def("__exit__", [](igtl::IngestClient& c, const py::args&) {
        py::gil_scoped_release release;
        c.Stop();
      });
}

}  // namespace echoservo::python
