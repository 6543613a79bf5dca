"""The benchmarks' harnesses: what scripts/benchmark_*.py run and report (planner, registration, perception,
latency, command stream), each judged on the simulator's or the generator's ground truth."""
