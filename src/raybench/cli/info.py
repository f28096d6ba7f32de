"""raybench info: this machine's processors, their FP32 rates, library versions."""

from __future__ import annotations

import json

import click


@click.command()
@click.option("--json", "as_json", is_flag=True, help="print the machine description as JSON")
def info(as_json):
    """Describe this machine: processors, their FP32 rates, library versions."""
    from ..machine import describe

    desc = describe()
    if as_json:
        from .out import echo

        echo(json.dumps(desc, indent=2))
        return
    c = desc["cpu"]
    click.echo(f"OS        {desc['os']}")
    click.echo(f"CPU       {c['model']} ({c['arch']})")
    click.echo(
        f"          {c['physical_cores']} cores, {c['logical_cpus']} logical CPUs, {c['clock_ghz']} GHz, "
        f"{c['memory_gib']} GiB memory"
    )
    click.echo(
        f"          SIMD {c['simd']} ({c['simd_bits']} bits = {c['fp32_lanes']} float32 lanes), "
        f"{c['fma_units_per_core']} FMA units per core (assumed)"
    )
    click.echo(
        f"          FP32 peak {c['fp32_gflops']:,} GFLOP/s = {c['physical_cores']} cores x {c['clock_ghz']} GHz "
        f"x {c['fp32_lanes']} lanes x 2 x {c['fma_units_per_core']} FMA units"
    )
    if not desc["gpus"]:
        from ..backends import cuda_available

        click.echo("GPU       none usable" + ("" if cuda_available() else f": {_cuda_reason()}"))
    for g in desc["gpus"]:
        click.echo(f"GPU       {g['name']} (compute capability {g['compute_capability']}, driver {g['driver']})")
        click.echo(
            f"          {g['multiprocessors']} multiprocessors x {g['fp32_lanes_per_sm']} FP32 lanes, "
            f"{g['clock_ghz']} GHz, memory {g['memory_gib']} GiB at {g['memory_clock_ghz']} GHz"
        )
        if g["fp32_gflops"]:
            click.echo(
                f"          FP32 peak {g['fp32_gflops']:,} GFLOP/s = {g['multiprocessors']} x "
                f"{g['fp32_lanes_per_sm']} x 2 x {g['clock_ghz']} GHz"
            )
    adapters = desc["wgpu_adapters"]
    if not adapters:
        click.echo("wgpu      no adapter found (no Vulkan, Metal, D3D12 or OpenGL driver wgpu can use)")
    for i, a in enumerate(adapters):
        note = "" if a["type"] in ("DiscreteGPU", "IntegratedGPU") else "  (not a GPU: used only with --adapter)"
        click.echo(
            f"{'wgpu' if i == 0 else ''}{'':{10 - (4 if i == 0 else 0)}}{a['name']} ({a['backend']}, {a['type']}){note}"
        )
    versions = ", ".join(f"{k} {v}" for k, v in desc["versions"].items() if v)
    click.echo(f"Versions  {versions}")


def _cuda_reason() -> str:
    try:
        from ..backends.cuda import device

        return device.reason()
    except ImportError as exc:
        return f"numba-cuda is not installed: {exc}"
