# A stand-in for a node: says hello with its arguments, then ticks until signalled.  It exits
# quietly on SIGINT (how the supervisor stops nodes) even when the signal comes while Python is
# still starting (before the handler is set): no KeyboardInterrupt traceback in its log.
try:
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
except KeyboardInterrupt:
    pass
