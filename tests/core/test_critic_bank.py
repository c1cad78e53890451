"""The pseudo-critic bank as one batched ensemble (`CriticBank`): the same mathematics as
separate per-head MLPs (outputs, gradients, clipped Adam updates), and checkpoints of the
per-head layout (the first shipped Kuafu policies were written in it) load into it unchanged."""

from __future__ import annotations

import pytest
import torch

from coadapt_core.learning.networks import CriticBank, ValueNet


def _pair(
    inputs: int = 11, design: int = 2, hidden=(32, 16, 8), heads: int = 3
) -> tuple[ValueNet, CriticBank]:
    """A per-head ValueNet and a bank built from the same seed (hence the same weights)."""
    torch.manual_seed(7)
    per_head = ValueNet(inputs, design, hidden, "elu", outputs=heads)
    torch.manual_seed(7)
    bank = CriticBank(inputs, design, hidden, "elu", heads)
    return per_head, bank


def _data(n: int = 64, inputs: int = 11, design: int = 2, heads: int = 3):
    gen = torch.Generator().manual_seed(3)
    return (
        torch.randn(n, inputs, generator=gen),
        torch.rand(n, design, generator=gen) * 2 - 1,
        torch.randn(n, heads, generator=gen),
    )


def test_bank_is_initialised_as_separate_heads_and_computes_the_same_outputs() -> None:
    per_head, bank = _pair()
    for h, head in enumerate(per_head.heads):
        linears = [m for m in head if isinstance(m, torch.nn.Linear)]
        for k, linear in enumerate(linears):
            assert torch.equal(bank.layer(k)[0][h], linear.weight)
            assert torch.equal(bank.layer(k)[1][h], linear.bias)
    x, d, _ = _data()
    out = bank(x, d)
    assert out.shape == (64, 3)
    assert torch.allclose(out, per_head(x, d), atol=1e-6)
    assert not torch.allclose(out[:, 0], out[:, 1])  # heads are distinct networks
    # leading dims [N, T, *] as in compute_returns
    assert torch.allclose(
        bank(x.reshape(8, 8, -1), d.reshape(8, 8, -1)), out.reshape(8, 8, 3), atol=1e-6
    )


def test_bank_gradients_and_clipped_adam_updates_equal_the_per_head_version() -> None:
    per_head, bank = _pair()
    opt_a = torch.optim.Adam(per_head.parameters(), lr=1e-2, foreach=True)
    opt_b = torch.optim.Adam(bank.parameters(), lr=1e-2, foreach=True)
    x, d, y = _data()
    for step in range(5):
        for net, opt in ((per_head, opt_a), (bank, opt_b)):
            opt.zero_grad(set_to_none=True)
            loss = torch.nn.functional.mse_loss(net(x, d), y)
            loss.backward()
            norm = torch.nn.utils.clip_grad_norm_(net.parameters(), 0.05, foreach=True)
            if net is per_head:
                norm_a = norm
            else:
                norm_b = norm
            if step == 0 and net is bank:  # gradients match before the first step
                for h, head in enumerate(per_head.heads):
                    linears = [m for m in head if isinstance(m, torch.nn.Linear)]
                    for k, linear in enumerate(linears):
                        assert torch.allclose(
                            bank.layer(k)[0].grad[h], linear.weight.grad, atol=1e-6
                        )
                        assert torch.allclose(bank.layer(k)[1].grad[h], linear.bias.grad, atol=1e-6)
            opt.step()
        assert float(norm_a) == pytest.approx(float(norm_b), rel=1e-5)
        assert float(norm_a) > 0.05  # the clip was active, the global norm spans all heads
    converted = CriticBank.convert_state_dict(per_head.state_dict())
    for key, value in bank.state_dict().items():
        assert torch.allclose(value, converted[key], atol=1e-5), key
    assert torch.allclose(bank(x, d), per_head(x, d), atol=1e-5)


def test_per_head_optimizer_state_converts_and_continues_identically() -> None:
    per_head, bank = _pair()
    x, d, y = _data()
    opt_a = torch.optim.Adam(per_head.parameters(), lr=1e-2, foreach=True)
    for _ in range(3):
        opt_a.zero_grad()
        torch.nn.functional.mse_loss(per_head(x, d), y).backward()
        opt_a.step()
    bank.load_state_dict(CriticBank.convert_state_dict(per_head.state_dict()))
    opt_b = torch.optim.Adam(bank.parameters(), lr=1e-2, foreach=True)
    opt_b.load_state_dict(
        CriticBank.convert_optimizer_state(opt_a.state_dict(), bank.num_heads, bank.num_layers)
    )
    for net, opt in ((per_head, opt_a), (bank, opt_b)):
        opt.zero_grad()
        torch.nn.functional.mse_loss(net(x, d), y).backward()
        opt.step()
    assert torch.allclose(bank(x, d), per_head(x, d), atol=1e-5)
    # a stacked state passes through unchanged; a state of another shape is dropped (fresh Adam)
    state_b = opt_b.state_dict()
    assert CriticBank.convert_optimizer_state(state_b, bank.num_heads, bank.num_layers) is state_b
    assert CriticBank.convert_optimizer_state(state_b, 5, bank.num_layers) is None


def test_a_per_head_checkpoint_predicts_the_same_through_the_bank(tmp_path) -> None:
    # a checkpoint written before the bank (per-head layout `heads.<h>.<layer>.*`) at the
    # shipped policies' sizes, saved and read back the way checkpoints are
    torch.manual_seed(11)
    per_head = ValueNet(83, 4, (512, 256, 128), "elu", outputs=3)
    torch.save({"pseudo_critic": per_head.state_dict()}, tmp_path / "old.pt")
    saved = torch.load(tmp_path / "old.pt", map_location="cpu", weights_only=True)["pseudo_critic"]
    assert any(key.startswith("heads.") for key in saved)
    bank = CriticBank(83, 4, (512, 256, 128), "elu", 3)
    bank.load_state_dict(CriticBank.convert_state_dict(saved))
    gen = torch.Generator().manual_seed(0)
    x, d = torch.randn(256, 83, generator=gen), torch.rand(256, 4, generator=gen) * 2 - 1
    with torch.no_grad():
        a, b = per_head(x, d), bank(x, d)
    assert torch.allclose(a, b, rtol=1e-5, atol=1e-5), float((a - b).abs().max())
    assert float(a.std()) > 0
