"""PCHCRunner: rsl-rl's OnPolicyRunner with self-describing, atomic, weights-only checkpoints and ONNX export,
and a training loop that stops on NaN, saves on Ctrl-C and prints one line per iteration."""

from __future__ import annotations

import copy
import os
import time

import numpy as np
import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner

from pchc_rsl.export.onnx_export import export_onnx
from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.runners.iteration_log import IterationLogger
from pchc_rsl.runners.widen_critic import widen_critic_inputs
from pchc_rsl.utils.distributed import init_process_group, shutdown_process_group, world
from pchc_rsl.utils.files import atomic_write
from pchc_rsl.utils.finite import RolloutNaNCheck, first_non_finite_tensor, first_non_finite_value
from pchc_rsl.utils.physics_overflow import PhysicsOverflow


class TrainingStopped(Exception):
    """Training ended early; ``checkpoint`` is the last good checkpoint (None if there is none)."""

    def __init__(self, message: str, checkpoint: str | None) -> None:
        super().__init__(message)
        self.checkpoint = checkpoint


class NonFiniteTraining(TrainingStopped):
    """A loss or a network parameter became NaN or inf."""


class TrainingInterrupted(TrainingStopped):
    """Ctrl-C (KeyboardInterrupt); the state at the interrupt was saved first."""


class PhysicsOverflowStopped(TrainingStopped):
    """The physics dropped contacts or constraint rows in a rollout (a MuJoCo Warp buffer too small); nothing of
    that rollout was learned from or saved."""


class PCHCRunner(OnPolicyRunner):
    """OnPolicyRunner whose checkpoints carry the resolved config they were trained with.

    ``config`` is a plain dict (str, numbers, lists, dicts) describing the task, so that a checkpoint can be
    evaluated or exported without guessing its settings, and loaded with ``torch.load(weights_only=True)``.
    Iterations count from 0; ``model_<it>.pt`` holds the state after iteration ``it``, and training resumed from it
    continues with iteration ``it + 1``.
    """

    def __init__(
        self,
        env: VecEnv,
        train_cfg: dict,
        log_dir: str | None = None,
        device: str = "cpu",
        config: dict | None = None,
        verbose: bool = False,
    ) -> None:
        super().__init__(env, train_cfg, log_dir, device)
        self.config = config or {}
        self.logger = IterationLogger(
            log_dir=log_dir, cfg=self.cfg, env_cfg=self.env.cfg, num_envs=self.env.num_envs,
            is_distributed=self.is_distributed, gpu_world_size=self.gpu_world_size,
            gpu_global_rank=self.gpu_global_rank, device=self.device, verbose=verbose, guard=self._check_finite,
        )
        self.written: list[str] = []
        """Checkpoints this runner wrote, oldest first."""
        self.last_good_checkpoint: str | None = None
        """The newest finite checkpoint this runner wrote or loaded."""
        self.completed_iteration: int | None = None
        """The last iteration that finished (and passed the finite check) in this process."""
        self._completed_state: dict | None = None
        """What a checkpoint of ``completed_iteration`` holds, copied when it finished (what Ctrl-C saves)."""
        self._collecting = self.current_learning_iteration
        """The iteration whose rollout runs (or ran last)."""

    # ---- training loop additions -------------------------------------------------------------------------------

    def learn(self, num_learning_iterations: int, init_at_random_ep_len: bool = False) -> None:
        """rsl-rl's loop (``_learning_loop``), plus: raise NonFiniteTraining (nothing of the bad iteration saved) and,
        on Ctrl-C, save the state as it was when the last iteration finished and raise TrainingInterrupted."""
        try:
            self._learning_loop(num_learning_iterations, init_at_random_ep_len)
        except KeyboardInterrupt:
            saved = self._save_on_interrupt()
            self.logger.stop_logging_writer()
            raise TrainingInterrupted("interrupted (Ctrl-C)", saved) from None
        except NonFiniteTraining:
            self.logger.stop_logging_writer()
            raise
        except PhysicsOverflow as error:
            self.logger.stop_logging_writer()
            kept = f"the last checkpoint, {self.last_good_checkpoint}, is intact" if self.last_good_checkpoint else (
                "no checkpoint was written")
            task = self.config.get("task", type(self.env).__name__)
            raise PhysicsOverflowStopped(
                f"{task}: stopped in iteration {self._collecting} without learning from it: "
                f"{error} ({kept})", self.last_good_checkpoint) from None
        finally:
            self._close_writer()
            shutdown_process_group()

    def _learning_loop(self, num_learning_iterations: int, init_at_random_ep_len: bool) -> None:
        """OnPolicyRunner.learn of rsl-rl 5.5, step for step, with the rollout in ``rollout`` (no host sync per
        step but the env's own)."""
        if init_at_random_ep_len:
            self.env.episode_length_buf = torch.randint_like(
                self.env.episode_length_buf, high=int(self.env.max_episode_length)
            )
        obs = self.env.get_observations().to(self.device)
        self.alg.train_mode()
        if self.is_distributed:
            print(f"Synchronizing parameters for rank {self.gpu_global_rank}...")
            self.alg.broadcast_parameters()
        self.logger.init_logging_writer()
        start_it = self.current_learning_iteration
        total_it = start_it + num_learning_iterations
        for it in range(start_it, total_it):
            self._collecting = it
            start = time.time()
            obs = self.rollout(obs)
            stop = time.time()
            collect_time, start = stop - start, stop
            with torch.inference_mode():
                self.alg.compute_returns(obs)
            loss_dict = self.alg.update()
            learn_time = time.time() - start
            self.current_learning_iteration = it
            self.logger.log(
                it=it, start_it=start_it, total_it=total_it, collect_time=collect_time, learn_time=learn_time,
                loss_dict=loss_dict, learning_rate=self.alg.learning_rate,
                action_std=self.alg.get_policy().output_std,
                rnd_weight=self.alg.rnd.weight if self.cfg["algorithm"].get("rnd_cfg") else None,
            )
            if self.logger.writer is not None and it % self.cfg["save_interval"] == 0:
                self.save(os.path.join(self.logger.log_dir, f"model_{it}.pt"))
        if self.logger.writer is not None:
            self.save(os.path.join(self.logger.log_dir, f"model_{self.current_learning_iteration}.pt"))
            self.logger.stop_logging_writer()

    def rollout(self, obs: TensorDict) -> TensorDict:
        """Collect ``num_steps_per_env`` transitions from ``obs`` (act, env step, store, book-keeping); the last
        observations. rsl-rl's per-step NaN check and episode book-keeping read the device at every step; here
        both stay on the device until the rollout ends (RolloutNaNCheck, IterationLogger), so a GPU rollout waits
        on the host only where the env itself does."""
        nan_check = RolloutNaNCheck() if self.cfg.get("check_for_nan", True) else None
        rnd = bool(self.cfg["algorithm"].get("rnd_cfg"))
        with torch.inference_mode():
            for _ in range(self.cfg["num_steps_per_env"]):
                actions = self.alg.act(obs)
                obs, rewards, dones, extras = self.env.step(actions.to(self.env.device))
                if nan_check is not None:
                    nan_check.add(obs, rewards, dones)
                obs, rewards, dones = obs.to(self.device), rewards.to(self.device), dones.to(self.device)
                self.alg.process_env_step(obs, rewards, dones, extras)
                self.logger.process_env_step(rewards, dones, extras, self.alg.intrinsic_rewards if rnd else None)
            if nan_check is not None:
                nan_check.raise_if_any()
        if hasattr(self.env, "physics_report"):  # once per rollout: buffer peaks, and a clear stop on an overflow
            self.logger.physics_stats = self.env.physics_report()
        return obs

    def _close_writer(self) -> None:
        """Flush and close the event files, also when training stopped early."""
        if self.logger.writer is not None and hasattr(self.logger.writer, "close"):
            self.logger.writer.close()
        self.logger.writer = None

    def _check_finite(self, it: int, loss_dict: dict) -> None:
        """Stop when an update produced NaN or inf (called by the logger right after each update)."""
        bad_loss = first_non_finite_value(loss_dict)
        bad = f"loss '{bad_loss}' is {loss_dict[bad_loss]}" if bad_loss is not None else None
        if bad is None:
            bad_tensor = first_non_finite_tensor(model_tensors(self.alg.save()))
            bad = f"'{bad_tensor}' holds NaN or inf" if bad_tensor is not None else None
        if bad is not None:
            kept = f"the last good checkpoint is {self.last_good_checkpoint}" if self.last_good_checkpoint else (
                "no checkpoint was written")
            raise NonFiniteTraining(
                f"training diverged at iteration {it}: {bad}; stopped without saving it ({kept}). "
                "Lower the learning rate (runner.algorithm.learning_rate=...) or check the rewards.",
                self.last_good_checkpoint,
            )
        self.completed_iteration = it
        if self.logger.log_dir is not None:  # rsl-rl saves right after this: the state a checkpoint of it holds
            self.current_learning_iteration = it
            self._completed_state = copy.deepcopy(self.checkpoint_contents())

    def _save_on_interrupt(self) -> str | None:
        """Save the last completed iteration as it was when it finished (not the weights, optimizer and random
        streams part-way into the next one), unless it is already saved; the path of the newest checkpoint. A run
        resumed from it continues exactly as the uninterrupted run did."""
        if self.completed_iteration is None or self.logger.log_dir is None or self._completed_state is None:
            return self.last_good_checkpoint
        path = os.path.join(self.logger.log_dir, f"model_{self.completed_iteration}.pt")
        if path not in self.written:
            self._write_checkpoint(path, self._completed_state)
            self.logger.save_model(path, self.completed_iteration)
        return path

    # ---- several processes -------------------------------------------------------------------------------------

    def _configure_multi_gpu(self) -> None:
        """rsl-rl's multi-GPU scheme (one process per GPU, ``cuda:LOCAL_RANK``, NCCL), or the same over Gloo on
        CPUs. Written out here rather than calling rsl-rl's, which would start the process group a second time
        ("trying to initialize the default process group twice") after ours gave its one-line error check."""
        world_size, rank, local_rank = world()
        self.gpu_world_size, self.gpu_global_rank, self.gpu_local_rank = world_size, rank, local_rank
        self.is_distributed = world_size > 1
        if not self.is_distributed:
            self.cfg["multi_gpu"] = None
            return
        self.cfg["multi_gpu"] = {"global_rank": rank, "local_rank": local_rank, "world_size": world_size}
        cuda = torch.device(self.device).type == "cuda"
        if cuda:
            if torch.device(self.device) != torch.device(f"cuda:{local_rank}"):
                raise ValueError(f"rank {rank} trains on {self.device}, but a torchrun process uses the GPU of its "
                                 f"local rank, cuda:{local_rank}; pass --device cuda and each rank takes its own.")
            torch.cuda.set_device(local_rank)  # before NCCL starts, so its communicator binds this GPU
        init_process_group("nccl" if cuda else "gloo", rank, world_size)

    # ---- checkpoints -------------------------------------------------------------------------------------------

    def checkpoint_contents(self, infos: dict | None = None) -> dict:
        """What a checkpoint holds now: networks, optimizer, iteration, config, random streams and env state."""
        saved = self.alg.save()
        saved["iter"] = self.current_learning_iteration
        saved["infos"] = infos
        saved["config"] = self.config
        saved["training_state"] = self.training_state()
        return saved

    def save(self, path: str, infos: dict | None = None) -> None:
        """Write the checkpoint atomically (temp file + rename); never replaces a file this runner did not write."""
        self._write_checkpoint(path, self.checkpoint_contents(infos))
        self.logger.save_model(path, self.current_learning_iteration)

    def _write_checkpoint(self, path: str, saved: dict) -> None:
        if os.path.exists(path) and path not in self.written:
            raise FileExistsError(f"{path} exists and was not written by this run; checkpoints are never replaced.")
        bad = first_non_finite_tensor(model_tensors(saved))
        if bad is not None:
            raise ValueError(f"Refusing to save {path}: '{bad}' holds NaN or inf.")
        atomic_write(path, lambda tmp: torch.save(saved, tmp))
        if path not in self.written:
            self.written.append(path)
        self.last_good_checkpoint = path

    def training_state(self) -> dict:
        """What continuing the run needs beyond the networks: the random number streams (torch, numpy, and the
        env's own generators) and the env's evolving state (e.g. the fall-recovery curriculum)."""
        name, key, position, has_gauss, cached_gaussian = np.random.get_state()
        numpy_rng = [name, torch.from_numpy(key.astype(np.int64)), int(position), int(has_gauss), float(cached_gaussian)]
        state = {"torch_rng": torch.get_rng_state(), "numpy_rng": numpy_rng}
        if torch.device(self.device).type == "cuda":  # this process' GPU only: reading every GPU's state waits on each
            state["cuda_rng"] = torch.cuda.get_rng_state(self.device)
        if hasattr(self.env, "state_dict"):
            state["env"] = self.env.state_dict()
        return state

    def restore_training_state(self, loaded: dict) -> None:
        """Continue the streams and env state saved with the checkpoint (a resumed run; not for evaluation, whose
        env and seed are its own). Checkpoints without them (or, released, with only the env's progress) are
        accepted: the run then continues from new streams."""
        state = loaded.get("training_state")
        if not state:
            return
        if "torch_rng" in state:  # a released checkpoint keeps only the env's progress
            torch.set_rng_state(state["torch_rng"])
        if "numpy_rng" in state:
            name, key, position, has_gauss, cached_gaussian = state["numpy_rng"]
            np.random.set_state((name, key.numpy().astype(np.uint32), position, has_gauss, cached_gaussian))
        if "cuda_rng" in state and torch.device(self.device).type == "cuda":
            saved = state["cuda_rng"]  # one GPU's state; older checkpoints hold a list, one per GPU
            index = torch.device(self.device).index or 0
            saved = saved[min(index, len(saved) - 1)] if isinstance(saved, (list, tuple)) else saved
            torch.cuda.set_rng_state(saved, self.device)
        if "env" in state and hasattr(self.env, "load_state_dict"):
            self.env.load_state_dict(state["env"])

    def load(
        self, path: str, load_cfg: dict | None = None, strict: bool = True, map_location: str | None = None,
        resume: bool = False, widen_critic: bool = False,
    ) -> dict | None:
        """Load a checkpoint written by ``save``; refuse one trained for another task. Training continues with the
        iteration after the checkpoint's (model_9.pt + 10 iterations ends at model_19.pt); ``resume=True`` also
        continues its random streams and env state, so 10 + 10 iterations equal 20 in one go. ``widen_critic``: a
        critic that observes more than the checkpoint's starts from its weights (runners/widen_critic.py)."""
        loaded = load_checkpoint(path, map_location or self.device)
        theirs, ours = loaded.get("config", {}).get("task"), self.config.get("task")
        if theirs is not None and ours is not None and theirs != ours:
            raise ValueError(f"{path} was trained on task '{theirs}', but this runner is set up for '{ours}'.")
        if widen_critic and (load_cfg is None or load_cfg.get("critic", True)):
            added = widen_critic_inputs(loaded["critic_state_dict"], self.alg._raw_critic)
            if added:
                print(f"The critic observes {added} inputs more than {path}'s: they start with zero weights.")
        try:
            load_iteration = self.alg.load(loaded, load_cfg, strict)
        except RuntimeError as error:
            lines = [line.strip() for line in str(error).strip().splitlines() if line.strip()]
            detail = next((line for line in lines[1:] if line.startswith(("size mismatch", "Missing", "Unexpected"))),
                          lines[0] if lines else "")
            raise ValueError(f"{path} does not fit this runner's networks: {detail[:300]}") from None
        if load_iteration:
            self.current_learning_iteration = loaded["iter"] + 1
        if resume:
            self.restore_training_state(loaded)
        self.last_good_checkpoint = path
        return loaded.get("infos")

    def export_onnx(self, path: str, verbose: bool = False, metadata: dict | None = None) -> str:
        """Export the deterministic policy (inputs ``obs``, ``preference``), with ``metadata`` for a deploy, and
        check it against torch."""
        return export_onnx(self.alg.get_policy(), path, verbose=verbose, metadata=metadata)


def model_tensors(saved: dict):
    """(name, tensor) of every network weight and statistic in a checkpoint dict (optimizer state left out)."""

    def walk(prefix: str, value):
        if isinstance(value, torch.Tensor):
            yield prefix, value
        elif isinstance(value, dict):
            for key, item in value.items():
                if "optimizer" in str(key):
                    continue
                yield from walk(f"{prefix}.{key}" if prefix else str(key), item)

    for key, value in saved.items():
        if key.endswith("state_dict") and "optimizer" not in key:
            yield from walk(key, value)
