#pragma once
// CPU clocks for the pipeline's statistics. Per-stage costs are measured in
// the calling thread's CPU time, not wall time: on a shared machine wall time
// also counts the slices other processes hold the core.
// Times [s] of CPU (a thread's or the process's), not wall clock.
// Thread safety: the functions are safe from any thread. A CpuStopwatch
// measures the thread that reads it: construct and read it on one thread.
namespace lshloc {

/// [s] CPU time of the calling thread so far.
double thread_cpu_seconds();

/// [s] CPU time of this process so far (all threads).
double process_cpu_seconds();

/// Measures the calling thread's CPU time from its construction.
class CpuStopwatch {
 public:
  CpuStopwatch() : start_(thread_cpu_seconds()) {}
  double seconds() const { return thread_cpu_seconds() - start_; }

 private:
  double start_;
};

}  // namespace lshloc
