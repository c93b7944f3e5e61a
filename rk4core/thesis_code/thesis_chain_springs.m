function [m, k] = thesis_chain_springs(P, driver)
% THESIS_CHAIN_SPRINGS  Masses and springs (wall-m1, m1-m2, ..., mn-wall) of
% a linear problem whose stiffness matrix is a chain's between two walls,
% read from P.stiffness_matrix and P.masses (not from the model's name).
  if ~isfield(P, 'stiffness_matrix') || ~isfield(P, 'masses')
    error('%s: the problem has no stiffness_matrix (model %s is not linear)', driver, P.model);
  end
  K = P.stiffness_matrix;
  m = P.masses(:)';
  n = numel(m);
  if ~isequal(size(K), [n n])
    error('%s: stiffness_matrix is %dx%d for %d masses', driver, rows(K), columns(K), n);
  end
  k = zeros(1, n + 1);
  k(2:n) = -diag(K, 1)';
  k(1) = K(1,1) - k(2);
  k(n+1) = K(n,n) - k(n);
  Kchain = diag(k(1:n) + k(2:n+1)) - diag(k(2:n), 1) - diag(k(2:n), -1);
  if norm(K - Kchain, 1) > 1e-12 * norm(K, 1)
    error('%s: the stiffness matrix of model %s is not a chain''s between two walls', driver, P.model);
  end
end
