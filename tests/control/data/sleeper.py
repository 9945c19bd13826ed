# A stand-in for a node: says hello with its arguments, then ticks until signalled.
import signal
import sys
import time

signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
print("sleeper started", " ".join(sys.argv[1:]), flush=True)
tick = 0
while True:
    time.sleep(0.5)
    tick += 1
    print(f"tick {tick}", flush=True)
