"""``python -m activetrack.kernels``: compile every kernel into numba's disk cache (setup)."""

from activetrack.kernels import warm_up

if __name__ == "__main__":
    for module, seconds in warm_up().items():
        print(f"{module}: ready in {seconds:.1f} s")
