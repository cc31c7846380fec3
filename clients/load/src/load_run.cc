#include "occgeo/load/load_run.h"

#include <algorithm>
#include <chrono>
#include <thread>

#include "load_common.h"
#include "query_clients.h"
#include "robot_driver.h"
#include "server_process.h"

namespace occgeo::load {

namespace {

using namespace internal;  // NOLINT(google-build-using-namespace): the parts this file puts together

std::uint32_t entries_per_request(QueryKind kind, const LoadOptions& options) {
  switch (kind) {
    case QueryKind::collision_batch:
    case QueryKind::clearance_batch:
    case QueryKind::raycast_batch:
    case QueryKind::occupancy_batch:
      return options.batch;
    case QueryKind::swept_batch:
      return std::min<std::uint32_t>(options.batch, 1000);
    case QueryKind::ptem:
      return options.ptem_points;
    default:
      return 1;
  }
}

}  // namespace

LoadReport run_load(const LoadOptions& options, std::ostream& progress) {
  ErrorLog errors;
  std::unique_ptr<StartedServer> started;
  client::Endpoint endpoint;
  std::optional<int> server_pid = options.server_pid;
  if (options.server) {
    endpoint = *options.server;
  } else {
    started = std::make_unique<StartedServer>(options.occgeod, options.server_config);
    endpoint.host = "127.0.0.1";
    endpoint.port = started->port();
    server_pid = started->pid();
  }
  if (options.progress) progress << "occgeo-load: server " << endpoint.to_string() << '\n';

  // A robot that maps the world before measuring and whose footprint the queries use; its session stays open.
  std::atomic<bool> stop_robots{false};
  RobotDriver seeder(options, endpoint, kSeedRobotId, options.seed, 0.0, errors);
  const auto seed_start = Clock::now();
  seeder.run_lockstep_batches(options.warmup_scans, stop_robots);
  if (options.progress) {
    progress << "occgeo-load: " << options.warmup_scans << " warm-up scans in "
             << std::chrono::duration<double>(Clock::now() - seed_start).count() << " s\n";
  }

  std::vector<std::unique_ptr<RobotDriver>> robots;
  for (std::uint32_t i = 0; i < options.robots; ++i) {
    const double heading = 2.0 * std::numbers::pi * static_cast<double>(i) / std::max<double>(options.robots, 1.0);
    robots.push_back(std::make_unique<RobotDriver>(options, endpoint, "load-robot-" + std::to_string(i),
                                                   options.seed + 1 + i, heading, errors));
  }

  ClientShared shared{options, endpoint, {}, {}, errors};
  for (const auto& [kind, weight] : options.mix) {
    if (weight == 0) continue;
    shared.kinds.push_back(kind);
    shared.cumulative.push_back((shared.cumulative.empty() ? 0 : shared.cumulative.back()) + weight);
  }
  const std::size_t kind_slots = shared.kinds.size() + 1;  // + the observers' polls
  std::vector<std::unique_ptr<ClientThread>> threads;
  const std::uint32_t thread_count =
      std::max<std::uint32_t>(1, std::min(options.threads, std::max(options.clients, options.observers)));
  for (std::uint32_t t = 0; t < thread_count; ++t) {
    auto thread = std::make_unique<ClientThread>();
    thread->result.per_kind.resize(kind_slots);
    thread->result.errors_per_kind.resize(kind_slots);
    threads.push_back(std::move(thread));
  }
  for (std::uint32_t i = 0; i < options.clients; ++i) {
    ClientThread& thread = *threads[i % thread_count];
    thread.clients.push_back(std::make_unique<QueryClient>(shared, thread.result, thread.io, options.seed * 7919 + i));
  }
  for (std::uint32_t i = 0; i < options.observers; ++i) {
    ClientThread& thread = *threads[i % thread_count];
    thread.observers.push_back(std::make_unique<Observer>(shared, thread.result, thread.io));
  }

  // Go: robots and clients together; the window opens once everyone runs.
  std::atomic<bool> go{false};
  std::vector<std::thread> robot_threads;
  for (auto& robot : robots) {
    robot_threads.emplace_back([&robot, &stop_robots, &errors, fifo = options.robot_sched_fifo] {
      if (fifo) set_this_threads_policy(SCHED_FIFO, kRobotFifoPriority, "--robot-sched fifo", errors);
      try {
        robot->run(stop_robots);
      } catch (const std::exception& error) {
        errors.add(std::string("robot: ") + error.what());
      }
    });
  }
  for (auto& thread : threads) {
    thread->thread = std::thread([&thread, &shared, &go] { thread->run(shared, go); });
  }
  const auto server_ticks_start = server_pid ? process_cpu_ticks(*server_pid) : std::nullopt;
  const double own_cpu_start = own_cpu_seconds();
  std::vector<std::uint64_t> robot_scans_start;
  for (auto& robot : robots) robot_scans_start.push_back(robot->result().scans);
  const auto window_start = Clock::now();
  shared.measuring = true;
  go = true;

  const auto window = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.duration_s));
  std::uint64_t last_completed = 0;
  auto last_tick = window_start;
  while (Clock::now() < window_start + window) {
    std::this_thread::sleep_until(std::min(window_start + window, last_tick + std::chrono::seconds(1)));
    const auto now = Clock::now();
    const std::uint64_t completed = shared.completed.load();
    if (options.progress) {
      char line[200];
      std::snprintf(
          line, sizeof line, "occgeo-load: t=%.0f s  queries/s=%.0f  errors=%llu\n",
          std::chrono::duration<double>(now - window_start).count(),
          static_cast<double>(completed - last_completed) / std::chrono::duration<double>(now - last_tick).count(),
          static_cast<unsigned long long>(errors.count()));
      progress << line << std::flush;
    }
    if (started && !started->alive()) {
      errors.add("the server exited during the run: " + started->log_tail());
      break;
    }
    last_completed = completed;
    last_tick = now;
  }
  shared.measuring = false;
  shared.stopping = true;
  const auto window_end = Clock::now();
  const double window_s = std::chrono::duration<double>(window_end - window_start).count();

  LoadReport report;
  report.duration_s = window_s;
  report.robots = options.robots;
  report.clients = options.clients;
  report.depth = options.depth;
  report.observers = options.observers;
  report.client_threads = static_cast<std::uint32_t>(threads.size());
  report.client_sched_batch = options.client_sched_batch;
  report.robot_sched_fifo = options.robot_sched_fifo;
  if (server_pid) {
    const auto ticks_end = process_cpu_ticks(*server_pid);
    if (server_ticks_start && ticks_end) {
      report.server_measured = true;
      report.server_cpu_cores =
          static_cast<double>(*ticks_end - *server_ticks_start) / static_cast<double>(sysconf(_SC_CLK_TCK)) / window_s;
      const auto [rss, peak] = process_memory_kb(*server_pid);
      report.server_rss_kb = rss;
      report.server_peak_rss_kb = peak;
    }
  }
  report.client_cpu_cores = (own_cpu_seconds() - own_cpu_start) / window_s;

  stop_robots = true;
  for (auto& thread : robot_threads) thread.join();
  for (auto& thread : threads) thread->thread.join();

  // The server must still answer after the run.
  try {
    auto check = client::PipelinedConnection::open(endpoint, make_hello(v1::ROLE_QUERY, "occgeo-load-check"), 1);
    v1::ClientMessage status;
    status.mutable_status();
    check->call(std::move(status));
  } catch (const client::ClientError& error) {
    report.server_alive = false;
    errors.add(std::string("the server does not answer after the run: ") + error.what());
  }
  if (started && !started->alive()) {
    report.server_alive = false;
    errors.add("the server exited: " + started->log_tail());
  }

  Samples all_queries;
  for (std::size_t k = 0; k < kind_slots; ++k) {
    Samples samples;
    KindReport kind;
    kind.kind = k < shared.kinds.size() ? std::string(query_kind_name(shared.kinds[k])) : "observer_status";
    for (auto& thread : threads) {
      samples.insert(samples.end(), thread->result.per_kind[k].begin(), thread->result.per_kind[k].end());
      kind.errors += thread->result.errors_per_kind[k];
    }
    if (k == shared.kinds.size()) {
      report.observer_polls = samples.size();
      for (auto& thread : threads) {
        report.observer_events += thread->result.watch_events;
        if (options.observer_watch && options.observers > 0) {
          report.observer_dropped = report.observer_dropped.value_or(0) + thread->result.watch_dropped;
        }
      }
      if (options.observers == 0) break;
    } else {
      all_queries.insert(all_queries.end(), samples.begin(), samples.end());
    }
    std::sort(samples.begin(), samples.end());
    kind.completed = samples.size();
    kind.per_s = static_cast<double>(samples.size()) / window_s;
    kind.entries_per_s = kind.per_s * (k < shared.kinds.size() ? entries_per_request(shared.kinds[k], options) : 1.0);
    kind.p50_us = quantile_us(samples, 0.5);
    kind.p99_us = quantile_us(samples, 0.99);
    kind.p999_us = quantile_us(samples, 0.999);
    kind.max_us = samples.empty() ? 0.0 : static_cast<double>(samples.back()) / 1000.0;
    report.kinds.push_back(kind);
  }
  std::sort(all_queries.begin(), all_queries.end());
  report.queries = all_queries.size();
  report.queries_per_s = static_cast<double>(all_queries.size()) / window_s;
  report.p50_us = quantile_us(all_queries, 0.5);
  report.p99_us = quantile_us(all_queries, 0.99);
  report.p999_us = quantile_us(all_queries, 0.999);

  Samples ingest;
  Samples command;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    report.scans += robots[i]->result().scans - robot_scans_start[i];
    ingest.insert(ingest.end(), robots[i]->result().ingest.begin(), robots[i]->result().ingest.end());
    command.insert(command.end(), robots[i]->result().command.begin(), robots[i]->result().command.end());
    robots[i]->close();
  }
  seeder.close();
  std::sort(ingest.begin(), ingest.end());
  report.scans_per_s = static_cast<double>(report.scans) / window_s;
  double ingest_sum_ns = 0.0;
  for (const std::uint64_t sample : ingest) ingest_sum_ns += static_cast<double>(sample);
  report.ingest_mean_us = ingest.empty() ? 0.0 : ingest_sum_ns / static_cast<double>(ingest.size()) / 1000.0;
  report.ingest_p50_us = quantile_us(ingest, 0.5);
  report.ingest_p99_us = quantile_us(ingest, 0.99);
  std::sort(command.begin(), command.end());
  report.commands = command.size();
  report.command_p50_us = quantile_us(command, 0.5);
  report.command_p99_us = quantile_us(command, 0.99);

  report.errors = errors.count();
  report.error_samples = errors.samples();
  return report;
}

}  // namespace occgeo::load
