"""What the tests (and the benchmarks in bench/) share: starting and stopping processes,
waiting for an observable event, a free port, test doubles of the onboard process, and
message samples. Nothing here is a test, and nothing here imports a test module or bench/.
"""
