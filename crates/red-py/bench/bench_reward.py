"""RED's reward on a batch of pairs from Python: red (Rust through PyO3)
against the same RND networks written in numpy and, when importable, in
PyTorch, all on one thread.

    python crates/red-py/bench/bench_reward.py [--batch 1 1024] [--repeats 200]

The networks are the release's RND (target 4 x 128 leaky relu, predictor
1 x 128, outputs 128), fitted by red on the shipped demo with seed 0; the
numpy and PyTorch copies read their weights from red's model file and are
checked against red's rewards before timing. Not part of CI.
"""

import argparse
import json
import os
import pathlib
import tempfile
import time

# One thread for every library, set before numpy or torch load their BLAS.
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS"):
    os.environ[var] = "1"

import numpy as np  # noqa: E402

import red  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[3]
LEAKY_SLOPE = 0.2  # red-nets' LeakyRelu (TensorFlow's default, as the release)


def layers_of(net):
    """[(w (in, out) float32, b (out,) float32)] from red-nets' serialised MLP."""
    cfg = net["config"]
    widths = [cfg["input"], *cfg["hidden"], cfg["output"]]
    assert cfg["activation"] == "leaky_relu" and cfg["output_activation"] == "identity", cfg
    return [
        (np.asarray(l["w"], np.float32).reshape(i, o), np.asarray(l["b"], np.float32))
        for l, i, o in zip(net["layers"], widths[:-1], widths[1:])
    ]


def numpy_forward(layers, x):
    for k, (w, b) in enumerate(layers):
        x = x @ w + b
        if k + 1 < len(layers):
            x = np.where(x > 0, x, LEAKY_SLOPE * x)
    return x


def timed(fns, repeats):
    """{name: (wall median, 10th and 90th percentile, median on-CPU time of
    the calling thread)} of one call of each function. The calls are
    interleaved (one of each per round, the order rotating) so that every
    implementation sees the same load on a shared machine; the on-CPU time
    is the steadier measure (all the work runs on this thread)."""
    names = list(fns)
    for f in fns.values():
        f()  # warm up
    times = {n: [] for n in names}
    cpu = {n: [] for n in names}
    for r in range(repeats):
        for n in names[r % len(names):] + names[: r % len(names)]:
            t, c = time.perf_counter(), time.thread_time()
            fns[n]()
            cpu[n].append(time.thread_time() - c)
            times[n].append(time.perf_counter() - t)
    return {
        n: (
            float(np.median(times[n])),
            float(np.percentile(times[n], 10)),
            float(np.percentile(times[n], 90)),
            float(np.median(cpu[n])),
        )
        for n in names
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, nargs="+", default=[1024], help="batch sizes (pairs per call)")
    ap.add_argument("--repeats", type=int, default=200)
    args = ap.parse_args()

    demos = red.read_demos(ROOT / "data" / "drive-scripted-expert.json")
    obs, act = demos.pairs()
    reward = red.RedReward.fit("rnd", obs, act, seed=0)
    with tempfile.TemporaryDirectory() as d:
        reward.model.save(pathlib.Path(d) / "m.json")
        model = json.load(open(pathlib.Path(d) / "m.json"))["model"]["rnd"]
    mean = np.asarray(model["input"]["mean"], np.float64)
    scale = np.asarray(model["input"]["scale"], np.float64)
    (pair,) = model["pairs"]
    target, predictor = layers_of(pair["target"]), layers_of(pair["predictor"])
    sigma1 = reward.sigma1

    try:
        import torch
    except ImportError:
        torch = None
        print("PyTorch is not installed (pip install torch): no PyTorch figures")
    else:
        torch.set_num_threads(1)
        torch.set_num_interop_threads(1)

        def torch_net(layers):
            mods = []
            for k, (w, b) in enumerate(layers):
                lin = torch.nn.Linear(w.shape[0], w.shape[1])
                with torch.no_grad():
                    lin.weight.copy_(torch.from_numpy(w.T.copy()))
                    lin.bias.copy_(torch.from_numpy(b))
                mods.append(lin)
                if k + 1 < len(layers):
                    mods.append(torch.nn.LeakyReLU(LEAKY_SLOPE))
            return torch.nn.Sequential(*mods).eval()

        tnet, pnet = torch_net(target), torch_net(predictor)
        mean_t = torch.from_numpy(mean)
        scale_t = torch.from_numpy(scale)

    rng = np.random.default_rng(0)
    print(f"one thread; {args.repeats} calls of each, interleaved: wall median (p10-p90), on-CPU median of the calling thread")
    for batch in args.batch:
        idx = rng.integers(0, len(obs), size=batch)
        s = obs[idx] + rng.normal(scale=0.01, size=(batch, obs.shape[1]))
        a = np.clip(act[idx] + rng.normal(scale=0.1, size=(batch, act.shape[1])), -1, 1)

        def with_numpy():
            x = ((np.hstack([s, a]) - mean) / scale).astype(np.float32)
            d = numpy_forward(predictor, x) - numpy_forward(target, x)
            return np.exp(-sigma1 * (d * d).mean(axis=1, dtype=np.float64))

        def with_red():
            return reward.reward(s, a)

        ref = with_red()
        checks = {"numpy": np.abs(with_numpy() - ref).max()}
        fns = {"red (Rust, PyO3)": with_red, "numpy": with_numpy}
        if torch is not None:
            # The same call as red's: float64 numpy arrays in, float64 numpy out.
            def with_torch():
                with torch.inference_mode():
                    x = ((torch.from_numpy(np.hstack([s, a])) - mean_t) / scale_t).float()
                    d = pnet(x) - tnet(x)
                    return torch.exp(-sigma1 * (d * d).double().mean(dim=1)).numpy()

            # PyTorch's best case: the standardised float32 input already a
            # tensor, only the two networks and the reward timed.
            x_ready = ((torch.from_numpy(np.hstack([s, a])) - mean_t) / scale_t).float()

            def with_torch_nets_only():
                with torch.inference_mode():
                    d = pnet(x_ready) - tnet(x_ready)
                    return torch.exp(-sigma1 * (d * d).mean(dim=1))

            checks[f"PyTorch {torch.__version__}"] = np.abs(with_torch() - ref).max()
            checks["PyTorch, networks only"] = np.abs(with_torch_nets_only().double().numpy() - ref).max()
            fns[f"PyTorch {torch.__version__}"] = with_torch
            fns["PyTorch, networks only"] = with_torch_nets_only
        for name, err in checks.items():
            # Rewards are in (0, 1]; float32 networks agree to ~1e-6.
            assert err <= 1e-5, f"{name} differs from red by {err:.2e}"

        results = timed(fns, args.repeats)
        print(f"batch {batch} (max |reward - red's|: "
              + ", ".join(f"{k} {v:.1e}" for k, v in checks.items()) + ")")
        base, base_cpu = results["red (Rust, PyO3)"][0], results["red (Rust, PyO3)"][3]
        for name, (med, p10, p90, cpu) in results.items():
            print(
                f"  {name:<24} wall {med * 1e3:8.3f} ms ({p10 * 1e3:.3f}-{p90 * 1e3:.3f}) = {med / base:5.2f}x red's;"
                f"  CPU {cpu * 1e3:8.3f} ms = {cpu / base_cpu:5.2f}x red's;  {batch / cpu:,.0f} pairs/s on-CPU"
            )


if __name__ == "__main__":
    main()
