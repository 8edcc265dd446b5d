# hw/io: the file formats (CSV tables, EM-tracker logs, the trial format, RUN records and
# the durable append/replace files they are written with).
list(APPEND HW_SOURCES
  io/csv_table.cc
  io/durable_file.cc
  io/em_log.cc
  io/run_record.cc
  io/trial_io.cc)
