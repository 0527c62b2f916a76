#!/usr/bin/env python3
"""Loads the TensorBoard event files of a run directory with TensorBoard's own reader and
prints each scalar tag with its number of points and last (step, value), and each image tag
(the videos of `render_every`) with its images' steps, sizes and formats.

A manual check that `apo train` writes event files TensorBoard understands; not run by CI.

    python3 -m venv /tmp/tb && /tmp/tb/bin/pip install tensorboard
    /tmp/tb/bin/python scripts/check_tensorboard.py runs/Pendulum-v1-apo-s0

Exits 1 when the directory holds no scalar.
"""

import argparse
import sys

from tensorboard.backend.event_processing.event_accumulator import EventAccumulator


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="run directory holding events.out.tfevents.* files")
    args = parser.parse_args()

    # size_guidance 0: keep every point instead of TensorBoard's reservoir sample.
    accumulator = EventAccumulator(args.run, size_guidance={"scalars": 0, "images": 0})
    accumulator.Reload()
    tags = accumulator.Tags()["scalars"]
    if not tags:
        print(f"no scalars in {args.run}", file=sys.stderr)
        return 1
    for tag in sorted(tags):
        events = accumulator.Scalars(tag)
        last = events[-1]
        print(f"{tag}: {len(events)} points, last step {last.step} = {last.value:g}")
    for tag in sorted(accumulator.Tags()["images"]):
        for image in accumulator.Images(tag):
            kind = "GIF" if image.encoded_image_string.startswith(b"GIF8") else "PNG/other"
            print(
                f"{tag}: step {image.step}, {image.width}x{image.height}, "
                f"{len(image.encoded_image_string)} bytes, {kind}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
