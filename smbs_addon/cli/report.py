"""What the command line prints after a bake: the statistics in a few lines, the error bar and its price."""
from __future__ import annotations
from ..core.compiles import counted

def _cap_note(trials: dict) -> str:
    share = trials.get("capped_share_min", 0.0)
    return f" (at least {share:.1%} of the layer missing: raise max_trials)" if trials.get("capped") else ""


def summary_lines(stats: dict) -> list[str]:
    lines = [f"scene '{stats['scene']}': {stats['method']}, {stats['resolution'][0]}x{stats['resolution'][1]}, "
             f"{stats['time_s']:.2f} s, {stats['rays']:,} rays"]
    if stats.get("nothing_to_bake"):
        return lines + [f"  nothing to bake: {stats['nothing_to_bake']}; the caustic layer is all zero"]
    if stats.get("compile_s"):
        lines.append(f"  of which compiling the kernels for this machine: {stats['compile_s']:.1f} s "
                     f"({counted(stats.get('kernels_compiled', 0), 'kernel')}; once after installing or updating, "
                     f"later bakes load them from the cache)")
    plan = stats.get("plan", {})
    if plan.get("rays"):
        lines.append(f"  plan: {plan['rays']:,} rays ({plan.get('pilot_photons', 0):,} pilot photons), "
                     f"{plan['time_s']:.2f} s")
    if "walks" in stats:
        lines.append(f"  manifold walks: {stats['walks']:,}, success rate {stats['success_rate']:.1%}, "
                     f"{stats['mutations_per_path']:.2f} mutations per path "
                     f"({stats['mutations_per_success']:.1f} per solution found), "
                     f"chains {', '.join(stats['chain_types'])}")
    for name, s in stats["lights"].items():
        if "walks" in s:
            lm = ", ".join(f"{k} {v:,}" for k, v in s.get("large_mutations", {}).items())
            anchor = (f"{s['anchor_walks']:,} straight-line walks (success "
                      f"{s.get('anchor_successes', 0) / s['anchor_walks']:.1%}); from random seeds " if s.get("anchor_walks")
                      else "")
            lines.append(f"  light '{name}': {anchor}{s['walks']:,} walks, success {s['success_rate']:.1%}, "
                         f"{s['mutations_per_path']:.2f} mutations/path ({s['mutations_per_success']:.1f}/solution), "
                         f"large mutations ({lm}), "
                         f"trials mean {s['trials']['mean']:.2f} max {s['trials']['max']} capped {s['trials']['capped']}"
                         f"{_cap_note(s['trials'])}, "
                         f"{s['rays']:,} rays, {s['time_s']:.2f} s")
        else:
            lines.append(f"  light '{name}': {s['photons']:,} light paths, {s['splats']:,} reached the camera, "
                         f"{s['rays_photon'] + s['rays_camera']:,} rays, {s['time_s']:.2f} s")
    sky = stats.get("sky")
    if sky:
        lines.append(f"  the rest of {sky['light']}'s map ({1 - sky['bright_share']:.0%} of its light, a sky): "
                     f"{sky['eye_paths']:,} paths traced from the receivers, "
                     f"{sum(v for k, v in sky.items() if k.startswith('rays_')):,} rays, {sky['time_s']:.2f} s")
    for sk in stats["skipped"]:  # also in the plan's words, printed before the bake
        lines.append(f"  skipped {sk['kind']} '{sk['name']}': {sk['reason']}")
    nz = stats["noise"]
    lines.append(f"  noise: mean {nz['mean']:.4g} over {nz['region_pixels']} caustic pixels, "
                 f"standard error {nz['std_error_of_mean']:.2g}, per-pixel relative noise {nz['relative_noise']:.1%}")
    lines.extend(error_lines(stats))
    if "textured_share" in stats:
        where = ("in R, G, B times the Diffuse Color pass Cycles rendered for the bake, and per unit albedo "
                 "(channels per_albedo_R/G/B) for relighting" if stats.get("rgb") == "complete" else
                 "per unit albedo (channels per_albedo_R/G/B) for the render's Diffuse Color pass to multiply, and "
                 "left out of the colour channels")
        lines.append(f"  textured receivers: {stats['textured_share']:.0%} of the layer lies on them where the camera "
                     f"sees them; it is written {where}")
    return lines


def error_lines(stats: dict) -> list[str]:
    """The bake's error bar and its price, in words (the CLI's summary)."""
    err, halve = stats.get("relative_error"), stats.get("seconds_to_halve_error")
    conv = stats.get("convergence", {})
    if not stats["noise"]["region_pixels"]:
        return ["  error: no caustic in the image, nothing to measure"]
    if err is None:
        return ["  error: unknown (one batch: no spread to measure; bake at least two)"]
    line = f"  error: +-{err:.1%} relative RMS per caustic pixel"
    if halve:
        line += (f"; halving it would take about {duration(halve)} more "
                 f"({conv.get('seconds_per_batch', 0.0):.2f} s per batch, 4x the batches)")
    out = [line]
    if stats.get("error_leaves_out"):
        out.append("  the error counts noise only, not " + "; ".join(stats["error_leaves_out"]))
    if conv.get("heavy_tail"):
        out.append("  warning: the error is not yet falling as the batches add up (rare bright paths "
                   "still turn up), so it and the time to halve it are optimistic")
    stop = stats.get("stopped_by")
    if stop in ("time", "noise"):
        out.append(f"  stopped by the {stop} rule after {stats.get('batches_done', 0)} batches")
    elif stop == "signal":
        out.append(f"  stopped by {stats.get('signal', 'a signal')} after {stats.get('batches_done', 0)} whole "
                   f"batches (--keep-partial: the batch under way was dropped)")
    budget = stats.get("settings", {}).get("time_budget", 0.0)
    work = stats.get("time_s", 0.0) - stats.get("compile_s", 0.0)  # the time rule's clock
    if stop == "time" and stats.get("batches_done", 0) <= 2 and work > 1.1 * budget:
        out.append(f"  warning: the {budget:g} s budget was shorter than the plan, the pre-pass and the two "
                   f"batches an error bar needs ({work:.1f} s)")
    return out


def duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s" if s >= 10 else f"{s:.1f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"
