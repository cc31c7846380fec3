#pragma once

// Whether this process may put a thread under SCHED_FIFO: the tests of the real-time options expect the policy where
// it may and the program's error or warning where it may not.

#include <sched.h>

namespace occgeo::testing {

// True when the calling thread could switch to SCHED_FIFO at `priority` (RLIMIT_RTPRIO may allow less than
// CAP_SYS_NICE does, so probe the priority the test needs); the thread is back under SCHED_OTHER afterwards.
inline bool may_run_realtime(int priority) {
  sched_param probe{};
  probe.sched_priority = priority;
  if (sched_setscheduler(0, SCHED_FIFO, &probe) != 0) return false;
  const sched_param normal{};
  sched_setscheduler(0, SCHED_OTHER, &normal);
  return true;
}

}  // namespace occgeo::testing
