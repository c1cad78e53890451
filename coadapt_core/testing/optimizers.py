"""Conformance suite for `Optimizer` plugins.

Supply a fixture `optimizer_cls` (the class). Optional fixture `optimizer_options` (dict of
extra constructor options, default {}) and `convergence_budget` (ask/tell rounds for the
sphere test, default 30).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import UserError
from coadapt_core.optimizer import Optimizer, OutOfBoundsProposal


def sphere(designs: np.ndarray, optimum: np.ndarray) -> np.ndarray:
    return ((designs - optimum) ** 2).sum(axis=1)


class OptimizerConformance:
    """Every optimizer: ask/tell contract, bounds, determinism, progress on a sphere."""

    @pytest.fixture
    def optimizer_options(self) -> dict:
        return {}

    @pytest.fixture
    def convergence_budget(self) -> int:
        return 30

    @pytest.fixture
    def convergence_tolerance(self) -> float:
        """Best sphere cost to reach (squared distance; 1e-4 = within 1 cm of scale)."""
        return 1e-4

    @pytest.fixture
    def space(self) -> DesignSpace:
        return DesignSpace([Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5)])

    @pytest.fixture
    def mixed_space(self) -> DesignSpace:
        return DesignSpace(
            [Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5), Discrete("m", (1, 2, 3))]
        )

    def _objectives(self, optimizer_cls: type[Optimizer]) -> int:
        return 2 if optimizer_cls.multi_objective else 1

    def _costs(
        self, optimizer_cls: type[Optimizer], designs: np.ndarray, optimum: np.ndarray
    ) -> np.ndarray:
        f = sphere(designs, optimum)
        if optimizer_cls.multi_objective:
            return np.stack([f, sphere(designs, optimum + 0.1)], axis=1)
        return f

    def test_is_optimizer_with_name(self, optimizer_cls: type[Optimizer]) -> None:
        assert issubclass(optimizer_cls, Optimizer)
        assert isinstance(optimizer_cls.name, str) and optimizer_cls.name

    def test_ask_returns_population_inside_bounds(
        self, optimizer_cls, optimizer_options, space
    ) -> None:
        opt = optimizer_cls(
            space,
            population=8,
            budget=3,
            seed=1,
            num_objectives=self._objectives(optimizer_cls),
            **optimizer_options,
        )
        expected = 1 if optimizer_cls.sequential else 8
        for _ in range(3):
            designs = opt.ask()
            assert designs.shape == (expected, 2)
            assert np.all(designs >= 0.5 - 1e-9) and np.all(designs <= 1.5 + 1e-9)
            opt.tell(designs, self._costs(optimizer_cls, designs, np.array([0.7, 1.2])))
        assert opt.done
        assert opt.iteration == 3

    def test_calls_the_base_initialiser(self, optimizer_cls, optimizer_options, space) -> None:
        """A constructor of its own calls `super().__init__(space, **kwargs)`: the base class
        checks the seed, options and initial designs and keeps the state a resume needs."""
        opt = optimizer_cls(
            space,
            population=4,
            budget=2,
            seed=3,
            num_objectives=self._objectives(optimizer_cls),
            **optimizer_options,
        )
        missing = [
            a
            for a in ("space", "seed", "options", "initial_designs", "iteration", "_history")
            if not hasattr(opt, a)
        ]
        assert not missing, (
            f"Optimizer.__init__ did not run (no {', '.join(missing)}): "
            "call super().__init__(space, **kwargs)"
        )
        assert opt.space is space and opt.seed == 3 and opt.iteration == 0

    def test_proposals_stay_inside_the_bounds_without_clipping(
        self, optimizer_cls, optimizer_options, space, mixed_space
    ) -> None:
        """Proposals lie inside the bounds as made: the base class clips one that does not,
        but warns (`OutOfBoundsProposal`), since the design evaluated is not the one proposed."""
        spaces = [space] + ([mixed_space] if optimizer_cls.supports_mixed else [])
        for sp in spaces:
            opt = optimizer_cls(
                sp,
                population=8,
                budget=4,
                seed=4,
                num_objectives=self._objectives(optimizer_cls),
                **optimizer_options,
            )
            optimum = np.array([0.55, 1.45, 1.0][: sp.dim])
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", OutOfBoundsProposal)
                while not opt.done:
                    d = opt.ask()
                    opt.tell(d, self._costs(optimizer_cls, d, optimum))
            clipped = [
                str(w.message) for w in caught if issubclass(w.category, OutOfBoundsProposal)
            ]
            assert not clipped, clipped[0]

    def test_same_seed_same_proposals(self, optimizer_cls, optimizer_options, space) -> None:
        runs = []
        for _ in range(2):
            opt = optimizer_cls(
                space,
                population=6,
                budget=3,
                seed=7,
                num_objectives=self._objectives(optimizer_cls),
                **optimizer_options,
            )
            seq = []
            for _ in range(3):
                d = opt.ask()
                seq.append(d)
                opt.tell(d, self._costs(optimizer_cls, d, np.array([0.9, 0.9])))
            runs.append(np.concatenate(seq))
        np.testing.assert_allclose(runs[0], runs[1])

    def test_finds_sphere_optimum_region(
        self, optimizer_cls, optimizer_options, space, convergence_budget, convergence_tolerance
    ) -> None:
        """Best cost after the budget is close to 0 (pure random sampling of the same number
        of designs reaches 1e-4 with probability below 10 %)."""
        optimum = np.array([0.62, 1.31])
        opt = optimizer_cls(
            space,
            population=10,
            budget=convergence_budget,
            seed=3,
            num_objectives=self._objectives(optimizer_cls),
            **optimizer_options,
        )
        first_best = None
        all_designs, all_costs = [], []
        while not opt.done:
            d = opt.ask()
            c = self._costs(optimizer_cls, d, optimum)
            opt.tell(d, c)
            all_designs.append(d)
            all_costs.append(c if c.ndim == 1 else c[:, 0])
            if first_best is None:
                first_best = float(np.min(all_costs[-1]))
        best = float(np.min(np.concatenate(all_costs)))
        assert best < convergence_tolerance, (
            f"best sphere cost {best:.2e} after {convergence_budget} rounds"
        )
        assert best <= first_best

    def test_initial_designs_are_the_first_proposals(
        self, optimizer_cls, optimizer_options, space
    ) -> None:
        """The loop trains the policy on K sampled designs and passes them as
        `initial_designs`: a population optimizer's first `ask` returns them; a sequential
        one's first n asks return the n rows in order."""
        n_obj = self._objectives(optimizer_cls)
        initial = space.sample(3 if optimizer_cls.sequential else 6, rng=np.random.default_rng(11))
        opt = optimizer_cls(
            space,
            population=6,
            budget=4,
            seed=2,
            num_objectives=n_obj,
            initial_designs=initial,
            **optimizer_options,
        )
        if optimizer_cls.sequential:
            asked = []
            for _ in range(len(initial)):
                d = opt.ask()
                asked.append(d[0])
                opt.tell(d, self._costs(optimizer_cls, d, np.array([1.0, 1.0])))
            first = np.stack(asked)
        else:
            first = opt.ask()
        np.testing.assert_allclose(
            first, initial, atol=1e-9, err_msg="initial_designs were not the first proposals"
        )
        if not optimizer_cls.sequential:
            opt.tell(first, self._costs(optimizer_cls, first, np.array([1.0, 1.0])))
        # and the search goes on from there as usual (the loop runs J rounds after them)
        while not opt.done:
            d = opt.ask()
            assert np.all(d >= 0.5 - 1e-9) and np.all(d <= 1.5 + 1e-9)
            opt.tell(d, self._costs(optimizer_cls, d, np.array([1.0, 1.0])))

    def test_initial_designs_of_wrong_shape_refused(
        self, optimizer_cls, optimizer_options, space
    ) -> None:
        with pytest.raises(UserError):
            optimizer_cls(
                space,
                population=6,
                budget=2,
                seed=0,
                num_objectives=self._objectives(optimizer_cls),
                initial_designs=np.ones((2, 5)),
                **optimizer_options,
            )

    @pytest.mark.parametrize("seed", [0, 1, 2**32 - 1, 2**32, 2**62 + 12345, 2**63 - 1])
    def test_any_seed_below_2_to_63_works(
        self, optimizer_cls, optimizer_options, space, seed
    ) -> None:
        """The loop derives seeds from the run seed and the iteration: any integer in
        [0, 2**63) must work, and the same seed must give the same proposals."""
        n_obj = self._objectives(optimizer_cls)
        runs = []
        for _ in range(2):
            opt = optimizer_cls(
                space, population=4, budget=2, seed=seed, num_objectives=n_obj, **optimizer_options
            )
            seq = []
            for _ in range(2):
                d = opt.ask()
                assert np.all(d >= 0.5 - 1e-9) and np.all(d <= 1.5 + 1e-9)
                seq.append(d)
                opt.tell(d, self._costs(optimizer_cls, d, np.array([0.8, 0.8])))
            runs.append(np.concatenate(seq))
        np.testing.assert_array_equal(runs[0], runs[1])

    def test_declared_options_are_well_formed_and_defaults_work(self, optimizer_cls, space) -> None:
        """`option_specs` are `PluginOption`s whose defaults pass their own checks; passing
        every default explicitly gives the same proposals as passing none; an undeclared
        option is refused."""
        from coadapt_core.options import check_specs

        specs = check_specs(optimizer_cls.option_specs, optimizer_cls.name)
        n_obj = self._objectives(optimizer_cls)
        explicit = {s.name: s.default for s in specs if s.default is not None}
        a = optimizer_cls(space, population=4, budget=1, seed=3, num_objectives=n_obj)
        b = optimizer_cls(space, population=4, budget=1, seed=3, num_objectives=n_obj, **explicit)
        np.testing.assert_array_equal(a.ask(), b.ask())
        with pytest.raises(UserError):
            optimizer_cls(
                space, population=4, budget=1, seed=3, num_objectives=n_obj, no_such_option_xyz=1
            )

    def test_rejects_bad_population(self, optimizer_cls, space) -> None:
        with pytest.raises(UserError):
            optimizer_cls(
                space, population=0, budget=3, num_objectives=self._objectives(optimizer_cls)
            )

    def test_mixed_space_handled_or_refused(
        self, optimizer_cls, optimizer_options, mixed_space
    ) -> None:
        n_obj = self._objectives(optimizer_cls)
        if not optimizer_cls.supports_mixed:
            with pytest.raises(UserError):
                optimizer_cls(
                    mixed_space, population=4, budget=2, num_objectives=n_obj, **optimizer_options
                )
            return
        opt = optimizer_cls(
            mixed_space, population=6, budget=4, seed=0, num_objectives=n_obj, **optimizer_options
        )
        optimum = np.array([1.0, 1.0, 3.0])
        for _ in range(4):
            d = opt.ask()
            assert set(np.unique(d[:, 2])) <= {1.0, 2.0, 3.0}
            mixed_space.validate_batch(d)
            opt.tell(d, self._costs(optimizer_cls, d, optimum))

    def test_state_round_trips_through_json_and_continues_identically(
        self, optimizer_cls, optimizer_options, space
    ) -> None:
        """`state_dict()` is plain JSON; an optimizer built with the same arguments and given
        that state proposes exactly what the original does, round after round."""
        n_obj = self._objectives(optimizer_cls)
        optimum = np.array([0.9, 0.8])

        def make():
            return optimizer_cls(
                space, population=6, budget=6, seed=5, num_objectives=n_obj, **optimizer_options
            )

        a = make()
        for _ in range(2):
            d = a.ask()
            a.tell(d, self._costs(optimizer_cls, d, optimum))
        text = json.dumps(a.state_dict())
        b = make()
        b.load_state_dict(json.loads(text))
        assert b.iteration == a.iteration == 2
        np.testing.assert_array_equal(b.final_population(), a.final_population())
        for _ in range(3):
            da, db = a.ask(), b.ask()
            np.testing.assert_array_equal(da, db)
            a.tell(da, self._costs(optimizer_cls, da, optimum))
            b.tell(db, self._costs(optimizer_cls, db, optimum))
        assert a.best()[1] == b.best()[1]
        assert json.dumps(a.state_dict()) == json.dumps(b.state_dict())

    def test_state_of_another_optimizer_is_refused(
        self, optimizer_cls, optimizer_options, space
    ) -> None:
        opt = optimizer_cls(
            space,
            population=4,
            budget=2,
            seed=0,
            num_objectives=self._objectives(optimizer_cls),
            **optimizer_options,
        )
        with pytest.raises(UserError):
            opt.load_state_dict({"optimizer": "not-" + optimizer_cls.name, "rounds": []})
