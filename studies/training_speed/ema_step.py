"""CPU per training step of the camera network with and without the weights' moving
average, side by side (alternating blocks of 20 steps, one thread, bfloat16 autocast).
Usage: python studies/training_speed/ema_step.py"""

import time

import numpy as np
import torch
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from finray.model import FinRayNet, NetConfig
from finray.train.loop import WeightAverage

torch.set_num_threads(1)
torch.manual_seed(0)
net = NetConfig(in_channels=1, base_channels=16, height=64, width=32, contact=True)
model = FinRayNet(net).to(memory_format=torch.channels_last)
opt = torch.optim.Adam(model.parameters(), 4e-4)
x = torch.rand(16, 1, 64, 32).to(memory_format=torch.channels_last)
s = torch.rand(16, 1, 64, 32)
averages = {
    "plain": None,
    "AveragedModel": AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(0.999)),
    "WeightAverage": WeightAverage(model, 0.999),
}


def step(average) -> None:
    with torch.autocast("cpu", dtype=torch.bfloat16):
        sp, fp, cp = model.forward_normalised_all(x)
    loss = ((sp.float() - s) ** 2).mean() + (fp.float() ** 2).mean() + (cp.float() ** 2).mean()
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    if isinstance(average, AveragedModel):
        average.update_parameters(model)
    elif average is not None:
        average.update()


for average in averages.values():  # warm-up, and each average's first (copying) update
    for _ in range(5):
        step(average)
ms = {name: [] for name in averages}
for _ in range(8):
    for name, average in averages.items():
        c = time.thread_time()
        for _ in range(20):
            step(average)
        ms[name].append((time.thread_time() - c) / 20 * 1e3)
for name, v in ms.items():
    print(f"{name}: {np.median(v):.2f} ms CPU per step (blocks: {np.round(v, 1).tolist()})")
