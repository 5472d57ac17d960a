"""SAC from pixels: DrQ's recipe (Kostrikov et al., 2020) on Stable-Baselines3's SAC.

``algorithm: drq_sac`` in a training YAML, or ``DrQSAC`` directly. It differs from SB3's SAC in two
ways, the two that make a CNN learn where the arm is from camera images:

* **One image encoder, trained by the critic loss; the actor reads its features detached**
  (SAC-AE, DrQ). SB3 cannot be told this: with ``share_features_extractor=True`` its critic
  computes the shared features with gradients off and its critic optimiser leaves the extractor
  out, so the CNN learns from the actor loss only (``ContinuousCritic.forward``,
  ``SACPolicy._build`` in SB3 2.x); with ``False`` actor and critics each train a CNN of their own
  (twice the cost, and the actor's still learns from the actor loss). ``DrQSAC`` puts the encoder
  into the critic's optimiser, out of the actor's, and overrides :meth:`DrQSAC.train`: SB3's
  losses (n-step discounts included), in DrQ's order: critic, actor, temperature (SB3 updates the
  temperature first), then the target networks. No gSDE.
* **Random shift**: each sampled batch's camera images (every image key of a dict observation, or
  an image observation; images as :func:`uniros.image_spaces.is_image` tells them, so a float depth
  map is a vector here as in SB3), observations and next observations independently, are padded by
  ``image_shift`` pixels (edge replicated) and cropped back at a random offset per image
  (:func:`random_shift`). Rollouts, evaluation and prediction see the images as they are.

The default features extractor of a dict observation with images is :class:`ImageEncoder`: each
image through NatureCNN, LayerNorm and tanh (DrQ's encoder head), next to the vector keys;
``ignore_keys`` leaves keys out (for a policy that must read the end effector from the image,
``ignore_keys: [achieved_goal]``). Other observations keep SB3's default extractor (an image
observation NatureCNN; without images this is SAC with one update order changed).

Each gradient step encodes the batch's observations once with gradients and the next observations
twice without (the online encoder for the next action, the Polyak-averaged target encoder for the
target Q), where SB3's ``train`` runs the CNN five times; the actor and temperature update on the
features computed before the critic's step (DrQ encodes again: one CNN pass less here).
``benchmarks/bench_pixel_learning.py`` (``pixels_strict``) measures it against the state observation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3 import SAC
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, NatureCNN
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.sac.policies import LOG_STD_MAX, LOG_STD_MIN

from uniros.image_spaces import is_image

__all__ = ["DrQSAC", "ImageEncoder", "random_shift"]


def random_shift(images: th.Tensor, pad: int) -> th.Tensor:
    """DrQ's augmentation of a ``(N, C, H, W)`` batch: each image padded by ``pad`` pixels on every
    side (edges replicated) and cropped back to ``H x W`` at an offset drawn per image from torch's
    generator. Float out; ``pad`` 0 returns the batch as floats."""
    if pad < 0:
        raise ValueError(f"random_shift: pad must be >= 0, got {pad}")
    if images.ndim != 4:
        raise ValueError(f"random_shift: expected a (N, C, H, W) batch, got shape {tuple(images.shape)}")
    if pad == 0:
        return images.float()
    n, c, h, w = images.shape
    device = images.device
    # A crop of the edge-replicated padding at offset (dy, dx) reads source pixel (y + dy - pad,
    # x + dx - pad) clamped into the image: one gather of those indices, no padded copy (6x faster
    # than padding and advanced indexing: 1.7 ms vs 10.7 ms for 128 x 3 x 48 x 48 on one CPU thread).
    rows = (th.randint(0, 2 * pad + 1, (n, 1), device=device) + th.arange(h, device=device) - pad).clamp_(0, h - 1)
    cols = (th.randint(0, 2 * pad + 1, (n, 1), device=device) + th.arange(w, device=device) - pad).clamp_(0, w - 1)
    index = (rows[:, :, None] * w + cols[:, None, :]).reshape(n, 1, h * w).expand(n, c, h * w)
    return images.flatten(2).gather(2, index).reshape(n, c, h, w).float()


class ImageEncoder(BaseFeaturesExtractor):
    """Every image key through NatureCNN to ``image_features``, LayerNorm and tanh; the other keys
    flattened next to them, in the observation's key order. ``ignore_keys`` are not read."""

    def __init__(self, observation_space: spaces.Dict, image_features: int = 50,
                 ignore_keys: Sequence[str] = ()) -> None:
        if not isinstance(observation_space, spaces.Dict):
            raise ValueError("ImageEncoder needs a dict observation space (MultiInputPolicy)")
        unknown = sorted(set(ignore_keys) - set(observation_space.spaces))
        if unknown:
            raise ValueError(f"ImageEncoder: ignore_keys {unknown} are not keys of the observation "
                             f"{list(observation_space.spaces)}")
        keys = [k for k in observation_space.spaces if k not in set(ignore_keys)]
        images = [k for k in keys if is_image(observation_space[k])]
        if not images:
            raise ValueError(f"ImageEncoder: no image among the keys it reads {keys}")
        vectors = [k for k in keys if k not in images]
        vector_dim = sum(int(np.prod(observation_space[k].shape)) for k in vectors)
        super().__init__(observation_space, image_features * len(images) + vector_dim)
        self.image_keys, self.vector_keys = images, vectors
        self.cnns = th.nn.ModuleDict({k: NatureCNN(observation_space[k], features_dim=image_features)
                                      for k in images})
        self.norms = th.nn.ModuleDict({k: th.nn.LayerNorm(image_features) for k in images})

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        parts = [th.tanh(self.norms[k](self.cnns[k](observations[k]))) for k in self.image_keys]
        parts += [observations[k].flatten(1) for k in self.vector_keys]
        return th.cat(parts, dim=1)


class DrQSAC(SAC):
    """SAC whose image encoder learns from the critic loss, on randomly shifted images (module
    docstring). Takes SAC's arguments, and ``image_shift`` (pixels, 0: no augmentation)."""

    def __init__(self, policy: Any, env: Any, *, image_shift: int = 4, **kwargs: Any) -> None:
        if not isinstance(image_shift, int) or isinstance(image_shift, bool) or image_shift < 0:
            raise ValueError(f"image_shift must be a whole number of pixels >= 0, got {image_shift!r}")
        policy_kwargs = dict(kwargs.pop("policy_kwargs", None) or {})
        if kwargs.get("use_sde"):
            raise ValueError("DrQSAC does not support gSDE (use_sde)")
        if policy_kwargs.get("share_features_extractor") is False:
            raise ValueError("DrQSAC shares one image encoder between actor and critics: "
                             "share_features_extractor cannot be False")
        policy_kwargs["share_features_extractor"] = True
        self.image_shift = image_shift
        super().__init__(policy, env, policy_kwargs=policy_kwargs, **kwargs)

    def _setup_model(self) -> None:
        space = self.observation_space
        if isinstance(space, spaces.Dict) and any(is_image(s) for s in space.spaces.values()):
            self.policy_kwargs.setdefault("features_extractor_class", ImageEncoder)
        super()._setup_model()
        encoder = {id(p) for p in self.actor.features_extractor.parameters()}
        policy, lr = self.policy, self.lr_schedule(1)
        # SB3 left the shared encoder out of the critic's optimiser; it goes in, and out of the actor's.
        self.critic.optimizer = policy.optimizer_class(self.critic.parameters(), lr=lr, **policy.optimizer_kwargs)
        self.actor.optimizer = policy.optimizer_class(
            [p for p in self.actor.parameters() if id(p) not in encoder], lr=lr, **policy.optimizer_kwargs)
        if isinstance(space, spaces.Dict):
            self._image_keys: list[str] | None = [k for k, s in space.spaces.items() if is_image(s)]
        else:
            self._image_keys = None if is_image(space) else []

    def _shifted(self, observations: Any) -> Any:
        if self.image_shift == 0 or self._image_keys == []:
            return observations
        if self._image_keys is None:
            return random_shift(observations, self.image_shift)
        out = dict(observations)
        for key in self._image_keys:
            out[key] = random_shift(out[key], self.image_shift)
        return out

    def _actor_from(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        actor = self.actor
        latent = actor.latent_pi(features)
        log_std = th.clamp(actor.log_std(latent), LOG_STD_MIN, LOG_STD_MAX)
        actions, log_prob = actor.action_dist.log_prob_from_params(actor.mu(latent), log_std)
        return actions, log_prob.reshape(-1, 1)

    @staticmethod
    def _q_from(critic: Any, features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        q_in = th.cat([features, actions], dim=1)
        return th.cat([q_net(q_in) for q_net in critic.q_networks], dim=1)

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        self.policy.set_training_mode(True)
        optimizers = [self.actor.optimizer, self.critic.optimizer]
        if self.ent_coef_optimizer is not None:
            optimizers.append(self.ent_coef_optimizer)
        self._update_learning_rate(optimizers)
        encoder, target_encoder = self.critic.features_extractor, self.critic_target.features_extractor
        ent_coef_losses, ent_coefs, critic_losses, actor_losses = [], [], [], []
        for step in range(gradient_steps):
            data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)  # type: ignore[union-attr]
            observations, next_observations = self._shifted(data.observations), self._shifted(data.next_observations)
            if self.ent_coef_optimizer is not None and self.log_ent_coef is not None:
                ent_coef = th.exp(self.log_ent_coef.detach())
            else:
                ent_coef = self.ent_coef_tensor
            ent_coefs.append(float(ent_coef.item()))
            features = self.policy.extract_features(observations, encoder)
            with th.no_grad():
                next_actions, next_log_prob = self._actor_from(
                    self.policy.extract_features(next_observations, encoder))
                next_q = self._q_from(self.critic_target, self.policy.extract_features(
                    next_observations, target_encoder), next_actions).min(dim=1, keepdim=True).values
                discounts = data.discounts if getattr(data, "discounts", None) is not None else self.gamma
                target_q = data.rewards + (1 - data.dones) * discounts * (next_q - ent_coef * next_log_prob)
            current_q = self._q_from(self.critic, features, data.actions)
            critic_loss = 0.5 * sum(F.mse_loss(current_q[:, k:k + 1], target_q) for k in range(current_q.shape[1]))
            assert isinstance(critic_loss, th.Tensor)
            critic_losses.append(float(critic_loss.item()))
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            detached = features.detach()
            actions_pi, log_prob = self._actor_from(detached)
            q_pi = self._q_from(self.critic, detached, actions_pi).min(dim=1, keepdim=True).values
            actor_loss = (ent_coef * log_prob - q_pi).mean()
            actor_losses.append(float(actor_loss.item()))
            self.actor.optimizer.zero_grad()
            actor_loss.backward()
            self.actor.optimizer.step()
            if self.ent_coef_optimizer is not None and self.log_ent_coef is not None:
                ent_coef_loss = -(self.log_ent_coef * (log_prob + self.target_entropy).detach()).mean()
                ent_coef_losses.append(float(ent_coef_loss.item()))
                self.ent_coef_optimizer.zero_grad()
                ent_coef_loss.backward()
                self.ent_coef_optimizer.step()
            if step % self.target_update_interval == 0:
                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
                polyak_update(self.batch_norm_stats, self.batch_norm_stats_target, 1.0)
        self._n_updates += gradient_steps
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/ent_coef", float(np.mean(ent_coefs)))
        self.logger.record("train/actor_loss", float(np.mean(actor_losses)))
        self.logger.record("train/critic_loss", float(np.mean(critic_losses)))
        if ent_coef_losses:
            self.logger.record("train/ent_coef_loss", float(np.mean(ent_coef_losses)))
